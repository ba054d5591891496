"""Helpers of the trace-check tests: the stored demo traces (testdata/*.ndjson.gz) and edits of them."""
import gzip
import json
from pathlib import Path

DATA = Path(__file__).resolve().parent / "testdata"


def load(name: str) -> list[dict]:
    """The records of testdata/NAME.ndjson.gz."""
    with gzip.open(DATA / f"{name}.ndjson.gz", "rt") as f:
        return [json.loads(line) for line in f if line.strip()]


def write(path: Path, recs: list[dict]) -> Path:
    """Writes @p recs as an NDJSON trace file at @p path."""
    path.write_text("".join(json.dumps(r) + "\n" for r in recs))
    return path


def nth(recs: list[dict], action: str, k: int = 0) -> int:
    """Index of the k-th record of @p action."""
    return [i for i, r in enumerate(recs) if r["action"] == action][k]
