"""Fixtures and Hypothesis profiles for the Python tests.

Hypothesis profiles (pick one with --hypothesis-profile=NAME):
  dev   the default: 500 examples per property (the differential ones take 4x that), well
        under a minute in all
  ci    the same, derandomized (reproducible) and without the example database; chosen
        automatically when the environment has CI=true
  long  20x as many examples, for a soak run (minutes)

The differential tests talk to the C++ codec through `$EV3_BIN/ev3-codec` (default: build/bin of
this checkout); one process per mode for the whole session. If the tool is missing they fail.
"""

from __future__ import annotations

import os
import select
import subprocess
import tempfile
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

REPO = Path(__file__).resolve().parents[2]

# --- Hypothesis profiles ---------------------------------------------------------------------

_COMMON = dict(
    deadline=None,  # a subprocess round trip has jitter; total runtime is what matters
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.register_profile("dev", max_examples=500, **_COMMON)
settings.register_profile("ci", max_examples=500, derandomize=True, database=None,
                          print_blob=True, **_COMMON)
settings.register_profile("long", max_examples=10000, **_COMMON)


def _in_ci() -> bool:
    return os.environ.get("CI", "").strip().lower() in ("1", "true", "yes")


# --hypothesis-profile, handled by Hypothesis's own pytest plugin, overrides this choice.
settings.load_profile("ci" if _in_ci() else "dev")


# --- Tests that run TLC ------------------------------------------------------------------------

# These run the model checker (the conformance checks replay, simulate and validate against the
# spec): marked `tlc`, so that `make check` can leave them out with -m "not tlc".
_TLC_TESTS = ("conformance", "test_replay_sample.py")


def pytest_collection_modifyitems(items):
    here = Path(__file__).resolve().parent
    for item in items:
        rel = Path(str(item.fspath)).resolve().relative_to(here)
        if rel.parts and rel.parts[0] in _TLC_TESTS:
            item.add_marker(pytest.mark.tlc)


# --- The C++ codec tool ----------------------------------------------------------------------

TOOL_TIMEOUT = 10.0  # seconds for one answer line


class CodecTool:
    """One `ev3-codec MODE` process: write a line, read the one line it answers.

    If the process dies or hangs on an input, the failure names the input and the tool's stderr,
    and the next call starts a fresh process (so Hypothesis can go on shrinking).
    """

    def __init__(self, path: Path, mode: str) -> None:
        self.path = path
        self.mode = mode
        self.lines = 0  # inputs answered, for the session summary
        self._proc: subprocess.Popen | None = None
        self._stderr = None
        self._buffer = b""

    def _start(self) -> None:
        self._stderr = tempfile.TemporaryFile()
        self._proc = subprocess.Popen([str(self.path), self.mode], stdin=subprocess.PIPE,
                                      stdout=subprocess.PIPE, stderr=self._stderr, bufsize=0)
        self._buffer = b""

    def _stderr_text(self) -> str:
        if self._stderr is None:
            return ""
        self._stderr.seek(0)
        return self._stderr.read().decode("utf-8", "replace")[-2000:]

    def _broken(self, what: str, line: str) -> AssertionError:
        proc, self._proc = self._proc, None
        if proc is not None and proc.poll() is None:
            proc.kill()
        if proc is not None:
            proc.wait()
            for pipe in (proc.stdin, proc.stdout):
                try:
                    pipe.close()
                except OSError:  # e.g. a broken pipe on flushing stdin
                    pass
        shown = line if len(line) <= 400 else line[:400] + f"... ({len(line)} chars)"
        err = AssertionError(
            f"ev3-codec {self.mode} {what} on the input line {shown!r}"
            f" (exit status {proc.returncode if proc else '?'}); its stderr:\n{self._stderr_text()}")
        return err

    def ask(self, line: str) -> str:
        if "\n" in line:
            raise ValueError("one line at a time")
        if self._proc is None or self._proc.poll() is not None:
            self._start()
        assert self._proc is not None and self._proc.stdin and self._proc.stdout
        try:
            self._proc.stdin.write(line.encode("ascii") + b"\n")
            self._proc.stdin.flush()
        except BrokenPipeError:
            raise self._broken("exited", line) from None
        fd = self._proc.stdout.fileno()
        deadline = time.monotonic() + TOOL_TIMEOUT
        while b"\n" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                raise self._broken(f"gave no answer within {TOOL_TIMEOUT:g} s", line)
            chunk = os.read(fd, 65536)
            if not chunk:
                raise self._broken("exited without answering", line)
            self._buffer += chunk
        answer, _, self._buffer = self._buffer.partition(b"\n")
        if self._buffer:
            raise self._broken(f"wrote more than one line (extra: {self._buffer[:200]!r})", line)
        self.lines += 1
        return answer.decode("utf-8", "replace")

    def close(self) -> None:
        if self._proc is not None:
            assert self._proc.stdin
            self._proc.stdin.close()
            try:
                self._proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait()
            assert self._proc.stdout
            self._proc.stdout.close()
            self._proc = None
        if self._stderr is not None:
            self._stderr.close()
            self._stderr = None


def _ev3_bin() -> Path:
    return Path(os.environ.get("EV3_BIN") or REPO / "build" / "bin")


@pytest.fixture(scope="session")
def ev3_codec_path() -> Path:
    path = _ev3_bin() / "ev3-codec"
    if not (path.is_file() and os.access(path, os.X_OK)):
        pytest.fail(
            f"the C++ codec tool {path} does not exist (or is not executable): the differential "
            f"tests need it. Build it with `make build`, or point EV3_BIN at the directory that "
            f"holds ev3-codec (EV3_BIN={os.environ.get('EV3_BIN', '<unset>')}).",
            pytrace=False)
    return path


_TOOLS: list[CodecTool] = []


def _tool(path: Path, mode: str):
    tool = CodecTool(path, mode)
    _TOOLS.append(tool)
    try:
        yield tool
    finally:
        tool.close()


@pytest.fixture(scope="session")
def codec_decode(ev3_codec_path):
    """`ev3-codec decode`, one process for the session."""
    yield from _tool(ev3_codec_path, "decode")


@pytest.fixture(scope="session")
def codec_encode(ev3_codec_path):
    """`ev3-codec encode`, one process for the session."""
    yield from _tool(ev3_codec_path, "encode")


def pytest_report_header(config):
    return [f"ev3-codec: {_ev3_bin() / 'ev3-codec'}"]


def pytest_terminal_summary(terminalreporter):
    if _TOOLS:
        counts = ", ".join(f"{t.lines} {t.mode}" for t in _TOOLS)
        terminalreporter.write_line(f"ev3-codec differential: lines answered: {counts}")
