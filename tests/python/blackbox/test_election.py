"""Relay and election with real programs over loopback UDP (docs/programs.md "Relay and election"):
ev3-master and three ev3-agent, all with --election; the master is killed (SIGKILL); the agents
elect one of them master of epoch 5 (the lowest --score; the PC published the membership one agent
per epoch while the three synced: epochs 2, 3, 4), the others follow it, and its
--master-script commands take effect; then the PC comes back from its state file and takes the fleet
back: agent #1's datagrams go through the test (ev3net.Links), which loses the PC's ELECT on its way
to #1, so the agent-master hears of the newer epoch from the PC's LEADER and hands over (HANDOVER).
With broadcast lists that make a line (#1 and #3 do not hear each other), #3 gets through #2's relay
and answers the new master's PINGs and commands through it.

These runs pass `--trace=FILE` themselves; conftest validates the agents' traces against AgentLogic
composed with Election.tla's per-agent rules (docs/spec.md "Election traces") and the master's against
MasterLogic composed with Election.tla's rules of the PC ("Election master traces")."""

from __future__ import annotations

import re
import signal
import time
from pathlib import Path

import pytest
from ev3conformance import merged

from ev3net import Links, Program, free_ports, read_status, trace_records, wait_until

HB, LOSS, PAUSED = 100, 600, 1200          # ms; back-off before standing: 3000 + score x 100
SCORES = (1, 20, 40)
SYNCED = 1 + len(SCORES)                   # the PC's epoch once the three are members (one step each)
WON = SYNCED + 1                           # the epoch the agents elect a master in


def log_lines(tmp: Path, name: str) -> list[str]:
    p = tmp / f"{name}.log"
    return p.read_text(errors="replace").splitlines() if p.exists() else []


def trace(tmp: Path, name: str) -> list[dict]:
    return trace_records(tmp / f"{name}.nd")


def start_fleet(master_exe, agent_exe, programs, tmp: Path, hears: dict[int, list[int]], links: Links | None = None):
    """The PC master and three agents with --election (agent i broadcasts to the PC and the agents
    hears[i]); with @p links, every datagram of agent #1 goes through them. Returns the agents' ids
    and a function that starts the PC master (again) with the trace and log NAME.nd / NAME.log."""
    mport, *aports = free_ports(4)
    if links:
        links.connect(aports[0], [mport, *aports[1:]])
    port = links.port if links else (lambda _sender, receiver: receiver)
    status = tmp / "status.json"

    def pc(name: str) -> Program:
        return Program(master_exe, ["--port", str(mport), "--bind", "127.0.0.1", "--election",
                                    "--state-file", str(tmp / "master.state"), "--status-json", str(status),
                                    "--record", str(tmp / "record.tsv"),
                                    *sum((["--broadcast", f"127.0.0.1:{port(mport, p)}"] for p in aports), []),
                                    f"--trace={tmp / f'{name}.nd'}", "--log-file", str(tmp / f"{name}.log")],
                       tmp, name)
    master = pc("master")
    script = tmp / "script.txt"
    script.write_text("wait 1.5\nbehaviour all wait seconds=0.5\nstart all\n")
    for i, p in enumerate(aports):
        (tmp / f"s{i + 1}").mkdir()
        programs.append(Program(agent_exe, [
            "--port", str(p), "--bind", "127.0.0.1",
            *sum((["--broadcast", f"127.0.0.1:{port(p, q)}"] for q in [mport] + [aports[j] for j in hears[i]]), []),
            "--heartbeat-ms", str(HB), "--master-timeout-ms", str(LOSS), "--paused-timeout-ms", str(PAUSED),
            "--election", "--score", str(SCORES[i]), "--state-dir", str(tmp / f"s{i + 1}"),
            "--master-script", str(script), "--sysfs-root", str(tmp / "nosys"),
            f"--trace={tmp / f'agent{i + 1}.nd'}", "--log-level", "2", "--log-file", str(tmp / f"agent{i + 1}.log")],
            tmp, f"agent{i + 1}"))
    ags = wait_until(lambda: (s := read_status(status)) and len(s["agents"]) == 3 and
                     all(a["state"] == "ACTIVE" for a in s["agents"]) and s["agents"], 5, "three ACTIVE agents")
    ids = {}
    for i in range(3):
        m = wait_until(lambda: next((re.search(r"state ACTIVE \(id (\d+)\)", l) for l in log_lines(tmp, f"agent{i + 1}")
                                     if "state ACTIVE (id" in l), None), 2, "agent id")
        ids[i] = int(m.group(1))
    assert sorted(ids.values()) == sorted(a["id"] for a in ags)
    # An agent stands only once it knows the membership: the PC's next LEADER (every second) lists them.
    wait_until(lambda: all(any(r["action"] == "HandleHeartbeat" and r["args"]["msg"].count(":") >= 8
                               for r in trace(tmp, f"agent{i + 1}")) for i in range(3)), 3, "LEADER with the members")
    master.stop(signal.SIGKILL)  # the PC dies
    master.close()
    return ids, pc


def winner_of(tmp: Path) -> list[tuple[int, str]]:
    return [(i, l) for i in range(3) for l in log_lines(tmp, f"agent{i + 1}") if "election: won epoch" in l]


@pytest.fixture
def links():
    """Agent #1's links to the PC and its peers through the test (ev3net.Links)."""
    lk = Links(3)
    yield lk
    lk.close()


def test_election_after_the_master_is_killed(master_exe, agent_exe, programs, tmp_path, links, merged_run):
    """The agents elect #1 when the PC is killed; then the PC takes the fleet back from it: with the
    PC's ELECT (and any EPOCH_STALE) lost on their way to agent #1, the agent-master first hears of
    the PC's newer epoch from its LEADER, so its Master core hands the fleet over (HANDOVER) and
    steps down (Election HandleHeartbeat, System MasterHandover); the PC takes the ids HANDOVER brought. The whole run's
    merged check (conftest) then holds a real HANDOVER: the test asserts the merged behaviour has the
    step-down record and the PC's MasterHandover after it, and that the same run with that Master
    core planted to stay master after its HANDOVER is refused naming HandoverStepsDownInv."""
    ids, pc = start_fleet(master_exe, agent_exe, programs, tmp_path, {0: [1, 2], 1: [0, 2], 2: [0, 1]}, links)
    t0 = time.monotonic()
    wait_until(lambda: winner_of(tmp_path), 12, "an agent to win an election")
    won = winner_of(tmp_path)
    assert len(won) == 1 and won[0][0] == 0 and f"won epoch {WON} (score 1)" in won[0][1], won  # the lowest score
    leader = ids[0]
    # The others follow it (ACTIVE, epoch WON), directly.
    for i in (1, 2):
        wait_until(lambda: any(f"following master {leader} (epoch {WON}) directly" in l
                               for l in log_lines(tmp_path, f"agent{i + 1}")), 4, f"agent{i + 1} to follow")
    # Its --master-script (after 1.5 s: a relayed agent needs up to relay_retry to join): BEHAVIOUR + START to both followers, which run it to ACTION_OK.
    for i in (1, 2):
        wait_until(lambda: any(f"master: agent {ids[i]}: ACTION_OK" in l for l in log_lines(tmp_path, "agent1")),
                   5, f"ACTION_OK of agent {ids[i]} at the new master")
    # Exactly one master in epoch WON (traces: BecomeMaster), epoch WON durable on every agent.
    masters = [i for i in range(3) if any(r["action"] == "BecomeMaster" for r in trace(tmp_path, f"agent{i + 1}"))]
    assert masters == [0]
    for i in range(3):
        state = (tmp_path / f"s{i + 1}" / "ev3-agent.state").read_text()
        assert state.startswith(f"epoch={WON}\n")
        # the membership is on the SD card too (a restarted agent can stand and vote with it): the
        # list of the new master's epoch, which it counted its votes against
        kv = dict(line.split("=", 1) for line in state.splitlines())
        assert kv["members"] == ",".join(str(x) for x in sorted(ids.values())), state
        assert kv["members_epoch"] == str(WON) and kv["floor"] == str(WON), state
    # Commands acted on in epoch WON came as EPOCH_CMD from the new master.
    applied = [r for r in trace(tmp_path, "agent2")
               if r["action"] == "ApplyCommand" and r["args"]["msg"].split(":")[4] == str(WON)]
    assert applied and all(r["args"]["msg"].split(":")[0] == str(leader) for r in applied)
    assert time.monotonic() - t0 < 15
    handover(pc, programs, links, leader, [ids[1], ids[2]], tmp_path, merged_run)


def handover(pc, programs, links, leader: int, others: list[int], tmp: Path, merged_run) -> None:
    """The PC comes back (same --state-file) while agent #1 (id @p leader) is master of epoch WON and
    ELECT / EPOCH_STALE are lost on their way to it: see test_election_after_the_master_is_killed."""
    pc_epoch = int(dict(line.split("=", 1) for line in (tmp / "master.state").read_text().splitlines())["epoch"])
    links.drop = {"ELECT", "EPOCH_STALE"}
    t0 = time.monotonic()
    programs.append(pc("master2"))
    core = f"master:{leader}:{WON}"

    def handed():
        down = next((r for r in trace(tmp, "agent1") if r["node"] == core and r["action"] == "HandleHeartbeat"
                     and r["changed"].get("life") == "STEPPED_DOWN"), None)
        took = next((r for r in trace(tmp, "master2") if r["action"] == "MasterHandover"), None)
        return down and took and (down, took)
    down, took = wait_until(handed, 10, f"agent-master {leader} to hand the fleet over to the PC (HANDOVER)")
    links.drop = set()
    print(f"\nthe PC back (from epoch {pc_epoch}): agent-master {leader} handed the fleet over after "
          f"{time.monotonic() - t0:.1f} s; lost on the way to it: {links.dropped}")
    assert links.dropped.get("ELECT"), links.dropped  # it never heard the PC's ELECT
    # the PC's LEADER of its new epoch made the Master core send HANDOVER (its msgid moved) and step down
    lead = down["args"]["msg"].split(":")
    e = int(lead[4])
    assert lead[0] == "1" and lead[3] == "29" and e > WON and down["changed"]["epoch"] == e, down
    assert "msgid" in down["changed"], down
    # the PC took HANDOVER(its new epoch, the agent-master's fleet) from it
    h = took["args"]["msg"].split(":")
    assert h[0] == str(leader) and h[3] == "32" and int(h[4]) == e and set(others) <= {int(x) for x in h[5:]}, took
    wait_until(lambda: any("(HANDOVER sent to the new master)" in l for l in log_lines(tmp, "agent1")), 2,
               "agent #1 to log its HANDOVER")
    wait_until(lambda: "election: the elected agent handed the fleet over (HANDOVER)" in (tmp / "master2.out").read_text(),
               2, "the PC to say it took the HANDOVER")
    # The PC's record has every report each agent made, once, in order: also those the agent-master
    # took and acknowledged while the PC was gone (its acknowledgement freed nothing; docs/reports.md).
    def made(i: int) -> int:
        return max((r["changed"]["made"] for r in trace(tmp, f"agent{i}") if "made" in r["changed"]), default=0)
    ids = {i: int(next(re.search(r"state ACTIVE \(id (\d+)\)", l) for l in log_lines(tmp, f"agent{i}")
                       if "state ACTIVE (id" in l).group(1)) for i in (1, 2, 3)}

    def recorded() -> dict[int, list[int]]:
        out: dict[int, list[int]] = {}
        for line in (tmp / "record.tsv").read_text().splitlines():
            if line and not line.startswith("#"):
                f = line.split("\t")
                assert f[3] == "report", line
                out.setdefault(int(f[0]), []).append(int(f[1]))
        return out
    want = {ids[i]: list(range(1, made(i) + 1)) for i in (1, 2, 3) if made(i)}
    assert any(want.get(x) for x in others), want  # the followers ran the agent-master's script
    wait_until(lambda: recorded() == want, 5, f"the PC's record to hold every report made ({want})")
    # The run ends here (SIGTERM, exit 0; a longer one only makes every trace check at teardown slower).
    for p in programs:
        assert p.stop() == 0, p.name
    # The merged behaviour the teardown check walks holds both: the PC's receive paired with the send.
    paths, epochs, loss = merged_run.inputs()
    assert epochs["master2.nd:master"] == pc_epoch
    m = merged.merge(paths, epochs)
    at = {(m.files[x.file].name, x.r["action"], x.r["args"].get("msg"), x.node): (i, x) for i, x in enumerate(m.order)}
    i_down, _ = at[("agent1.nd", "HandleHeartbeat", down["args"]["msg"], core)]
    i_took, x_took = at[("master2.nd", "MasterHandover", took["args"]["msg"], "master")]
    assert i_down < i_took and (x_took.file, x_took.k) in m.paired
    # The check bites on this run: its Master core planted to stay master after its HANDOVER must be
    # refused naming HandoverStepsDownInv (TLC, in the background as the checks at teardown).
    where = merged.plant(paths, tmp / "planted", "handover-keeps-master", loss)
    assert where.startswith("agent1.nd record ") and f"node {core} handed over to epoch {e}" in where, where
    merged_run.refused(tmp / "planted", epochs, loss, "HandoverStepsDownInv", where.split(" (")[0] + " ")


def test_relay_for_an_agent_that_hears_only_a_peer(master_exe, agent_exe, programs, tmp_path):
    # #1 and #3 do not hear each other: #3 reaches the new master (#1) only through #2.
    ids, _ = start_fleet(master_exe, agent_exe, programs, tmp_path, {0: [1], 1: [0, 2], 2: [1]})
    leader, relay, far = ids[0], ids[1], ids[2]
    wait_until(lambda: any(f"following master {leader} (epoch {WON}) through the relay of agent {relay}" in l
                           for l in log_lines(tmp_path, "agent3")), 14, "agent3 to follow through agent2's relay")
    # The new master's commands reach #3 through the relay and its answers come back.
    wait_until(lambda: any(f"master: agent {far}: ACTION_OK" in l for l in log_lines(tmp_path, "agent1")), 5,
               f"ACTION_OK of agent {far} (relayed) at the new master")
    assert any(f"master: agent {far}: START acknowledged" in l for l in log_lines(tmp_path, "agent1"))
    # PINGs answered through the relay: #3 stays synced well past the master timeout.
    time.sleep(3 * LOSS / 1000)
    t3 = trace(tmp_path, "agent3")  # (traces are flushed every 0.2 s)
    acts = [r["action"] for r in t3]
    assert "RequestRelay" in acts and "AcceptRelay" in acts
    offer = [r for r in t3 if r["action"] == "AcceptRelay"][-1]
    assert offer["args"]["msg"].split(":")[3] == "22" and offer["changed"]["via"] == relay  # RELAY_OFFER from #2
    k = max(j for j, r in enumerate(t3) if r["action"] == "AcceptRelay")
    assert not any(r.get("changed", {}).get("state") == "PANIC" for r in t3[k:]), "agent3 lost its relayed master"
    assert any(r["action"] == "RecvPong" for r in t3[k:])
    relay_acts = [r["action"] for r in trace(tmp_path, "agent2")]
    assert "OfferRelay" in relay_acts and "HandleAccept" in relay_acts and "Forward" in relay_acts


def test_agents_that_never_heard_the_pc_learn_the_membership_from_peers(master_exe, agent_exe, programs,
                                                                        tmp_path):
    """Liveness without the PC's list: the PC dies right after the sync, and the agents that could
    win never heard a LEADER listing the membership; they must learn it from a peer (ShareMembers /
    LearnMembers, at their first RELAY_REQ) and elect a master (without that rule the fleet would sit
    in PANIC until the PC came back). Five agents and the PC, 30 % loss, duplication and reordering on every
    sender. The PC's --broadcast list (LEADER, ELECT) names only #3, #4 and #5, which hear #1, #2 and
    the PC but not each other; #1 and #2 (the lowest scores) hear everyone, and the PC only by unicast
    (MASTER, PONG). #3-#5 sync first, so they are the PC's first three members and vote for each
    later step; #1 and #2 join last (epochs 5 and 6: list of five). The PC is killed as soon as the
    traces of #3-#5 hold its list of five (its LEADER of epoch 6: killed between its ELECT and that
    LEADER, #3-#5 would sit in epoch 6 with the list of four and #2 in epoch 5, and no agent here could
    gather pre-votes: docs/election.md, "a peer of a newer epoch"). Then #3-#5 know the list but cannot gather a
    majority of pre-votes (each hears only #1 and #2, which grant none to a weaker asker); #1 and #2
    have heard no LEADER at all: only a peer can tell them the list. With it, #1 (score 10) stands
    after its back-off and wins epoch 7: asserted within 10 s of the kill (4.7-5.4 s in 11 runs).
    Guards the fix: built with AgentElection::ShareMembersOk (election/agent.hpp) returning false at once
    (no agent ever sends a copy of its LEADER, so LearnMembers never runs), every run failed here
    (no agent master within the deadline); with the deadline at 30 s the five agents were still in
    PANIC at the end and none had stood (#1 and #2 know no list, #3-#5 get no pre-vote from them).
    Every node runs with --trace=FILE: conftest checks each node's trace (ElectionTrace /
    MasterElectionTrace, and the winner's Master core) and the whole run merged (ev3conformance.merged:
    two masters of one epoch, or a command obeyed from a stale master, fail it; the PC's last sends,
    lost with its SIGKILL, are taken as its own), as for the other tests of this file."""
    n, near = 5, (2, 3, 4)                 # indexes of #3, #4, #5: reached by the PC's broadcasts
    mport, *aports = free_ports(n + 1)
    status = tmp_path / "status.json"
    faults = ["--fault-loss", "30", "--fault-dup", "30", "--fault-reorder", "30"]
    master = Program(master_exe, ["--port", str(mport), "--bind", "127.0.0.1", "--election",
                                  "--state-file", str(tmp_path / "master.state"), "--status-json", str(status),
                                  *sum((["--broadcast", f"127.0.0.1:{aports[i]}"] for i in near), []),
                                  *faults, "--fault-seed", "13", f"--trace={tmp_path / 'master.nd'}",
                                  "--log-file", str(tmp_path / "master.log")],
                     tmp_path, "master")

    def start(i: int) -> None:
        hears = [j for j in range(n) if j != i and not (i in near and j in near)]
        (tmp_path / f"s{i + 1}").mkdir()
        programs.append(Program(agent_exe, [
            "--port", str(aports[i]), "--bind", "127.0.0.1",
            *sum((["--broadcast", f"127.0.0.1:{q}"] for q in [mport] + [aports[j] for j in hears]), []),
            "--heartbeat-ms", str(HB), "--master-timeout-ms", str(LOSS), "--paused-timeout-ms", str(PAUSED),
            "--election", "--score", str(10 * (i + 1)), "--state-dir", str(tmp_path / f"s{i + 1}"),
            *faults, "--fault-seed", str(100 + i), "--sysfs-root", str(tmp_path / "nosys"),
            f"--trace={tmp_path / f'agent{i + 1}.nd'}", "--log-level", "2", "--log-file", str(tmp_path / f"agent{i + 1}.log")],
            tmp_path, f"agent{i + 1}"))

    def pc_master_of(k: int) -> bool:
        return any(r["action"] == "BecomeMaster" and len(r["changed"].get("members", [])) == k
                   for r in trace(tmp_path, "master"))

    for i in near:
        start(i)
    wait_until(lambda: pc_master_of(len(near)), 20, "the PC master of #3-#5", interval=0.05)
    for i in range(n):
        if i not in near:
            start(i)
    # (The trace is flushed every 0.2 s; killed before that record is flushed, the PC's last election
    # would be missing from its trace and the merged check could not tell who leads that epoch.)
    wait_until(lambda: pc_master_of(n), 20, f"the PC master of the {n} agents", interval=0.005)
    # The PC writes a step's record before it sends the step's datagrams: its BecomeMaster in the trace
    # does not say that its LEADER left. The voters' traces do.
    wait_until(lambda: all(any(len(r.get("changed", {}).get("members", [])) == n for r in trace(tmp_path, f"agent{i + 1}"))
                           for i in near), 20, f"#3-#5 to hold the PC's list of {n}", interval=0.005)
    master.stop(signal.SIGKILL)
    master.close()
    t0 = time.monotonic()
    won = wait_until(lambda: [(i, l) for i in range(n) for l in log_lines(tmp_path, f"agent{i + 1}")
                              if "election: won epoch" in l], 10, "an agent to become master")
    elapsed = time.monotonic() - t0
    print(f"\nPC killed right after the sync of {n} agents (30 % loss, dup, reorder; its broadcasts reach "
          f"#3-#5 only): agent{won[0][0] + 1} {won[0][1].split('election: ')[1]} after {elapsed:.1f} s")
    # #1 and #2 heard no LEADER of the PC: the winner's list came from a peer (LearnMembers).
    for i in range(n):
        if i not in near:
            assert not any(r["action"] == "HandleHeartbeat" and r["args"]["msg"].split(":")[0] == "1"
                           for r in trace(tmp_path, f"agent{i + 1}")), f"agent{i + 1} heard the PC's LEADER"
    epochs = {}
    for i, line in won:
        e = int(re.search(r"won epoch (\d+)", line).group(1))
        assert epochs.setdefault(e, i) == i, f"two masters of epoch {e}: {won}"
    # The traces say the same: one BecomeMaster per epoch, by the agent whose log says it won.
    time.sleep(0.3)  # (traces are flushed every 0.2 s)
    became = []
    for i in range(n):
        epoch = None  # the agent's epoch as its trace has it (changed.epoch)
        for r in trace(tmp_path, f"agent{i + 1}"):
            if r.get("node") != "agent":
                continue  # its Master core's records (node master:ID:EPOCH)
            epoch = r.get("changed", {}).get("epoch", epoch)
            if r["action"] == "BecomeMaster":
                became.append((epoch, i))
    assert became, "no BecomeMaster in the agents' traces"
    assert len({e for e, _ in became}) == len(became), f"two BecomeMaster in one epoch: {became}"
    assert all((e, i) in became for e, i in epochs.items()), (became, epochs)
    winner = won[0][0]
    assert winner not in near, f"agent{winner + 1} won: it could not gather pre-votes"
    assert any(r["action"] == "LearnMembers" for r in trace(tmp_path, f"agent{winner + 1}"))


def test_a_damaged_membership_in_a_state_file_is_refused(master_exe, agent_exe, tmp_path):
    """The membership is kept with the epoch: a state file whose list is damaged, whose list
    lacks the epoch that published it or names one above the file's epoch, or (the agent's) whose
    floor is below that epoch, stops the program with the entry named (one rule for both programs,
    ev3proto/durable.hpp)."""
    import subprocess
    (tmp_path / "s").mkdir()
    cases = [
        (agent_exe, ["--election", "--state-dir", str(tmp_path / "s")], tmp_path / "s" / "ev3-agent.state",
         "epoch=3\nvoted_for=0\nmembers=2,x\nmembers_epoch=2\nfloor=2\n", "damaged: members: '2,x'"),
        (agent_exe, ["--election", "--state-dir", str(tmp_path / "s")], tmp_path / "s" / "ev3-agent.state",
         "epoch=3\nvoted_for=0\nmembers=2,3\nmembers_epoch=7\nfloor=2\n", "damaged: members_epoch: 7 is above epoch 3"),
        (agent_exe, ["--election", "--state-dir", str(tmp_path / "s")], tmp_path / "s" / "ev3-agent.state",
         "epoch=3\nvoted_for=0\nmembers=2,3\nmembers_epoch=3\nfloor=2\n", "damaged: floor: 2 is below members_epoch 3"),
        (master_exe, ["--election", "--state-file", str(tmp_path / "m.state")], tmp_path / "m.state",
         "next_id=5\nnext_msgid=100\nepoch=4\nmembers=2,3,4\n", "damaged: members_epoch: missing"),
        (master_exe, ["--election", "--state-file", str(tmp_path / "m.state")], tmp_path / "m.state",
         "next_id=5\nnext_msgid=100\nepoch=4\nmembers=2,3,4\nmembers_epoch=5\n", "damaged: members_epoch: 5 is above epoch 4"),
    ]
    for exe, args, path, text, said in cases:
        path.write_text(text)
        p = subprocess.run([str(exe), "--port", "0", "--bind", "127.0.0.1", *args], capture_output=True, text=True,
                           timeout=10)
        assert p.returncode == 2, (exe.name, text, p.returncode, p.stderr)
        assert said in p.stderr and str(path) in p.stderr, p.stderr
