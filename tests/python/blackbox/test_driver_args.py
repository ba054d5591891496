"""The arguments of `ev3-agent --driver` and `ev3-master --driver` (docs/driver.md), read by one
function for both programs: --help, --trace FILE (the last one counts), and clear errors."""

import json
import subprocess

import pytest

PROGRAMS = [("agent_exe", "ev3-agent", "agent"), ("master_exe", "ev3-master", "master")]


def run(exe, *args, stdin=""):
    return subprocess.run([str(exe), "--driver", *args], input=stdin, capture_output=True, text=True,
                          timeout=10)


@pytest.mark.parametrize("fixture,program,core", PROGRAMS)
def test_help_names_the_program_and_its_core(request, fixture, program, core):
    r = run(request.getfixturevalue(fixture), "--help")
    assert r.returncode == 0
    assert r.stdout.startswith(f"usage: {program} --driver [--trace FILE]")
    assert f"The {core} core on a virtual clock" in r.stdout


@pytest.mark.parametrize("fixture,program,core", PROGRAMS)
@pytest.mark.parametrize("args,said", [
    (["--bogus"], "--driver takes only --trace FILE (got '--bogus')"),
    (["--trace"], "bad value for --trace: cannot open ''"),
    (["--trace=/nonexistent-dir/t.ndjson"], "cannot open '/nonexistent-dir/t.ndjson'"),
])
def test_bad_arguments_exit_2_saying_why(request, fixture, program, core, args, said):
    r = run(request.getfixturevalue(fixture), *args)
    assert r.returncode == 2
    assert r.stderr.startswith(f"{program}: ") and said in r.stderr
    assert r.stdout == ""


@pytest.mark.parametrize("fixture,program,core", PROGRAMS)
def test_the_last_trace_file_gets_the_records(request, tmp_path, fixture, program, core):
    first, last = tmp_path / "first.ndjson", tmp_path / "last.ndjson"
    # The agent core records the Tick of the advance, the master core its MasterSync of the AGENT.
    r = run(request.getfixturevalue(fixture), "--trace", str(first), f"--trace={last}",
            stdin='{"type":"advance","ms":5}\n{"type":"recv","text":"50000:0:1:1:A"}\n')
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout.splitlines()[0])["ok"] is True
    assert first.read_text() == ""
    records = [json.loads(line) for line in last.read_text().splitlines()]
    assert records, "no trace records"
