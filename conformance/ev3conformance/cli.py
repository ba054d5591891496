"""ev3-conformance: command line of the conformance package.

    ev3-conformance codec decode HEX              decode a datagram given in hex
    ev3-conformance codec decode --text TEXT      decode a datagram given as its (ASCII) text
    ev3-conformance codec encode S R MSGID TYPE [PARAM ...]
                                                  encode a message; params as text (UTF-8),
                                                  or in hex with --hex ('-' for an empty one)

    ev3-conformance graph [--model agent]         TLC's state graph of the model: states, edges, paths
    ev3-conformance replay [--model agent|master|reports] [--driver CMD] [--known CLASS] [--sample N]
                                                  replay every edge against the driver (docs/driver.md);
                                                  agent --sample N: one in N of the ignored/duplicate
                                                  datagram edges (and one of each class)
    ev3-conformance replay --model fleet [--seed S] [--num N] [--depth D] [--election-num N]
                                   [--election-depth D]
                                                  TLC -simulate traces of the fleet replayed against
                                                  one master and one agent driver per agent
                                                  (--num 0: none), then those of the whole system
                                                  (System.tla: the PC's epochs, relay, pre-vote,
                                                  election, HANDOVER) against the PC's, the agents'
                                                  and the elected agents' Master cores' drivers
                                                  (--election-num 0: none)
    ev3-conformance validate TRACE... [--heartbeat MS ...] [--score N --epoch E --voted-for V]
                                                  check NDJSON traces (--trace) against the spec with TLC;
                                                  an --election agent's against AgentLogic + Election
    ev3-conformance validate --master TRACE... [--drop MS --resend MS --max-resends N]
                                                  master traces (ev3-master --driver, or the program
                                                  over UDP with its timers) against MasterLogic; an
                                                  --election master's with Election's rules of the PC
                                                  [--candidate --epoch E --members 2,3,4: its state file];
                                                  an --election agent's trace: its Master cores
                                                  (node master:ID:EPOCH; timers: ev3-agent's defaults)
    ev3-conformance merged DIR-or-TRACE... [--epoch FILE:NODE=E ...] [--master-timeout-ms MS]
                                                  the traces of every node of one run merged into one
                                                  behaviour (happens-before: process order, each receive
                                                  after its send) and checked with TLC against the
                                                  composed spec's own invariants (System.tla INSTANCEd
                                                  in spec/tla/trace/MergedTrace.tla): one master per
                                                  epoch, followers agree, relays one hop and acyclic,
                                                  no command from a stale master (fenced, newest epoch
                                                  told), lifecycle, no motion without a genuine master
                                                  datagram within MS (the agents' timeout, default
                                                  800), HANDOVER steps down
    ev3-conformance mutate [--only NAME ...] [--list]
                                                  mutation score: seeded core faults vs these checks

Exit status: codec: 0 accepted, 1 rejected, 2 usage error; graph/replay/validate/merged: 0 conforms,
1 mismatch (a report to paste into a bug), 2 usage or tool error.
"""

from __future__ import annotations

import argparse
import sys
import time

from ev3conformance import wire


def _show_param(value: bytes) -> str:
    """A param value as readable text: printable ASCII as itself, other bytes as \\xNN."""
    return "".join(chr(b) if 0x20 <= b <= 0x7E and b != 0x5C else f"\\x{b:02x}" for b in value)


def _describe(msg: wire.Message) -> str:
    name = msg.type_name or "?"
    lines = [
        f"sender   {msg.sender}",
        f"receiver {msg.receiver}",
        f"msgid    {msg.msgid}",
        f"type     {msg.type} {name}",
        f"params   {len(msg.params)}",
    ]
    mtype = wire.MESSAGE_TYPES.get(msg.type)
    for i, value in enumerate(msg.params):
        kind = mtype.kind_of(i) if mtype else "?"
        lines.append(f"  [{i}] field {wire.FIRST_PARAM_FIELD + i} {kind:5} \"{_show_param(value)}\"")
    return "\n".join(lines)


def _rejected(err: wire.DecodeError) -> int:
    print(f"rejected: {err.reason} (field {err.field})")
    return 1


def _cmd_decode(args: argparse.Namespace) -> int:
    if args.text:
        data = args.datagram.encode("latin-1")
    else:
        try:
            data = bytes.fromhex(args.datagram)
        except ValueError as exc:
            print(f"ev3-conformance: not hex: {exc}", file=sys.stderr)
            return 2
    try:
        msg = wire.decode(data)
    except wire.DecodeError as err:
        return _rejected(err)
    print("accepted")
    print(_describe(msg))
    print(f"datagram {wire.encode(msg).decode('ascii')}")
    return 0


def _cmd_encode(args: argparse.Namespace) -> int:
    params = []
    for p in args.params:
        if args.hex:
            try:
                params.append(b"" if p == "-" else bytes.fromhex(p))
            except ValueError as exc:
                print(f"ev3-conformance: param not hex: {exc}", file=sys.stderr)
                return 2
        else:
            params.append(p.encode("utf-8"))
    msg = wire.Message(args.sender, args.receiver, args.msgid, args.type, tuple(params))
    try:
        data = wire.encode(msg)
    except wire.DecodeError as err:
        return _rejected(err)
    print(data.decode("ascii"))
    return 0


MODELS = {"agent": ("MCAgent.tla", "MCAgent.cfg"), "master": ("MCMaster.tla", "MCMaster.cfg")}


def _cmd_graph(args: argparse.Namespace) -> int:
    from ev3conformance import graph, replay
    module, cfg = MODELS[args.model]
    g, figs = graph.dump_graph(module, cfg, args.model)
    c = graph.cfg_constants(module, cfg)
    r = replay.AgentReplay(g, c, [])
    ps = graph.cover(g, r.replayable)
    full = graph.cover(g)
    print(f"{args.model} ({module} {cfg}): states {len(g.states)}  edges {len(g.edges)}  "
          f"TLC {figs['tlc_seconds']}s  parse {figs['parse_seconds']}s")
    print(f"  paths covering every edge: {full.paths} (longest {full.max_len})")
    print(f"  paths covering every edge the core can take: {ps.paths} (longest {ps.max_len})")
    return 0


def _strict_replay(label: str, module: str, cfg: str, make, argv: list[str], known=()) -> int:
    """A strict replay of every edge of a model's state graph (master, reports): make(graph,
    constants, driver argv) gives the replay; prints the mismatches and the figures."""
    from ev3conformance import driver, graph
    g, figs = graph.dump_graph(module, cfg, label)
    r = make(g, graph.cfg_constants(module, cfg), argv)
    try:
        f = r.run()
    except driver.DriverError as e:
        print(f"driver failed: {e}")
        return 2
    f.tlc_seconds = figs["tlc_seconds"] + figs["parse_seconds"]
    for (act, flds), (n, rep) in sorted(f.classes.items(), key=lambda kv: -kv[1][0]):
        print(f"MISMATCH ({label}): {act} differs in [{', '.join(flds)}] on {n} edges; first one:")
        print(rep)
    print(f.summary())
    for k in known:
        print(f"KNOWN DIFFERENCE (spec vs core, reported, let pass with --known {k}): {f.tolerated} edges")
    print("replay: conforms" if not f.classes else "replay: FAIL")
    return 1 if f.classes else 0


def _cmd_replay_master(args: argparse.Namespace) -> int:
    import shlex
    from ev3conformance import driver, master_replay
    module, cfg = MODELS["master"]
    argv = shlex.split(args.driver) if args.driver else [str(driver.default_bin() / "ev3-master"), "--driver"]
    known = tuple(args.known or ())
    return _strict_replay("master", module, cfg, lambda g, c, a: master_replay.MasterReplay(g, c, a, known), argv,
                          known)


def _cmd_replay_reports(args: argparse.Namespace) -> int:
    import shlex
    from ev3conformance import driver, reports_replay as rr
    argv = shlex.split(args.driver) if args.driver else [str(driver.default_bin() / "ev3-reports-driver")]
    return max(_strict_replay(label, rr.MODULE, cfg, lambda g, c, a, n=label: rr.ReportsReplay(g, c, a, name=n), argv)
               for label, cfg in rr.CFGS)


def _cmd_replay_fleet(args: argparse.Namespace) -> int:
    import shlex
    from ev3conformance import driver, fleet_replay, system_replay
    agent = shlex.split(args.agent_driver or args.driver or "") or [str(driver.default_bin() / "ev3-agent"), "--driver"]
    master = shlex.split(args.master_driver or "") or [str(driver.default_bin() / "ev3-master"), "--driver"]
    # the fleet (MCFleetSim: --num 0, none), then the whole system with the election (MCSystemSim:
    # --election-num 0, none)
    if args.num < 0 or args.election_num < 0 or args.num == args.election_num == 0:
        print(f"ev3-conformance replay: --num {args.num} --election-num {args.election_num}: whole numbers, "
              "not both 0 (nothing to replay)")
        return 2
    parts = []
    if args.num > 0:
        parts.append(("fleet", fleet_replay.replay_simulation, args.num, args.depth, args.cfg))
    if args.election_num > 0:
        parts.append(("election", system_replay.replay_simulation, args.election_num, args.election_depth,
                      args.election_cfg))
    bad = False
    for label, replay_simulation, num, depth, cfg in parts:
        try:
            f = replay_simulation(args.seed, num, depth, agent, master, cfg)
        except driver.DriverError as e:
            print(f"driver failed: {e}")
            return 2
        except RuntimeError as e:
            print(e)
            return 2
        for (act, flds), (n, rep) in sorted(f.classes.items(), key=lambda kv: -kv[1][0]):
            print(f"MISMATCH ({label}): {act} differs in [{', '.join(flds)}] in {n} traces; first one:")
            print(rep)
        print(f"seed {args.seed}, {num} traces of depth <= {depth} ({cfg})")
        print(f.summary())
        bad = bad or bool(f.classes)
    print("replay: conforms" if not bad else "replay: FAIL")
    return 1 if bad else 0


def _cmd_replay(args: argparse.Namespace) -> int:
    import shlex
    from ev3conformance import driver, graph, replay
    if args.sample < 1 or args.sample != 1 and args.model != "agent":
        print(f"ev3-conformance replay: --sample {args.sample}: a whole number >= 1, for --model agent only")
        return 2
    if args.model == "master":
        return _cmd_replay_master(args)
    if args.model == "fleet":
        return _cmd_replay_fleet(args)
    if args.model == "reports":
        return _cmd_replay_reports(args)
    module, cfg = MODELS[args.model]
    argv = shlex.split(args.driver) if args.driver else [str(driver.default_bin() / "ev3-agent"), "--driver"]
    g, figs = graph.dump_graph(module, cfg, args.model)
    if figs.get("reused"):
        print(f"{args.model}: the state graph TLC dumped in make spec's run of the same spec (its digest)")
    c = graph.cfg_constants(module, cfg)
    r = replay.AgentReplay(g, c, argv, sample=args.sample)
    r.fig.tlc_seconds = figs["tlc_seconds"] + figs["parse_seconds"]
    try:
        f = r.run()
    except replay.Mismatch as m:
        print(m.report)
        print(f"FAIL after {r.fig.steps} steps ({r.fig.replayed} edges matched)")
        return 1
    except driver.DriverError as e:
        print(f"driver failed: {e}")
        return 2
    print(f.summary(args.model))
    print("replay: conforms")
    return 0


def _cmd_validate(args: argparse.Namespace) -> int:
    from ev3conformance import tracecheck
    if args.master:
        mc = {"TDrop": args.drop, "TResend": args.resend, "MaxResends": args.max_resends,
              "Behaviours": args.behaviour or ["wait"], "NextId": args.next_id, "FirstMsgid": args.first_msgid}
        # ev3-master --election (automatic when the trace has Election records): MasterLogic + Election's
        # rules of the PC, from the epoch / members / role it started with.
        if args.election is not None:
            mc["Election"] = args.election
        mc.update({"Epoch": args.epoch, "Members": [int(x) for x in args.members.split(",") if x.strip()],
                   "Life": "CANDIDATE" if args.candidate else "MASTER"})
        rs = []
        for p in args.traces:
            r = tracecheck.validate_master(p, mc)
            runs = tracecheck.agent_master_runs(p)  # an --election agent's trace: its Master cores
            if not (r.no_records and runs):  # an agent's trace holds no master program records
                rs.append(r)
            for node, c in runs:
                c.update({k: mc[k] for k in ("Behaviours",)})
                r2 = tracecheck.validate_master(p, c, node=node)
                r2.message = f"{node}: {r2.message}"
                rs.append(r2)
        bad = sum(not r.ok for r in rs)
        for r in rs:
            print(f"{'ok  ' if r.ok else 'FAIL'} {r.path}: {r.message}")
        print(f"validate --master: {len(rs) - bad} of {len(rs)} traces conform")
        return 1 if bad else 0
    # ev3-agent's rule (tracecheck.agent_timer_consts): a given master timeout doubled, else 10 heartbeats
    loss = args.loss if args.loss else 8 * args.heartbeat
    consts = {"TPing": args.heartbeat, "TLoss": loss, "TSync": args.sync,
              "TPaused": args.paused if args.paused else 2 * loss if args.loss else 10 * args.heartbeat}
    if args.window:
        consts["Window"] = args.window
    if args.election is not None:
        consts["Election"] = args.election
    consts.update({"Score": args.score, "Epoch": args.epoch, "VotedFor": args.voted_for})
    rs = tracecheck.validate_many(args.traces, consts, jobs=args.jobs)
    bad = 0
    for r in rs:
        print(f"{'ok  ' if r.ok else 'FAIL'} {r.path}: {r.message}")
        bad += not r.ok
    print(f"validate: {len(rs) - bad} of {len(rs)} traces conform")
    return 1 if bad else 0


def _cmd_merged(args: argparse.Namespace) -> int:
    from ev3conformance import merged
    epochs = {}
    for x in args.epoch or ():
        lab, _, e = x.rpartition("=")
        if not lab or not e.isdigit():
            print(f"ev3-conformance merged: --epoch {x!r}: expected FILE:NODE=EPOCH (agent1.nd:agent=2)", file=sys.stderr)
            return 2
        epochs[lab] = int(e)
    if args.loss is not None and args.loss <= 0:
        print(f"ev3-conformance merged: --master-timeout-ms {args.loss}: expected a positive number of ms",
              file=sys.stderr)
        return 2
    r = merged.validate(args.traces, epochs, loss=args.loss or merged.TLOSS)
    print(f"{'ok  ' if r.ok else 'FAIL'} merged run: {r.message}")
    print(f"merged: {'conforms' if r.ok else 'DOES NOT CONFORM'} ({r.records} records, {r.nodes} nodes, "
          f"{r.seconds:.1f} s)")
    return 0 if r.ok else 1


def _cmd_mutate(args: argparse.Namespace) -> int:
    from ev3conformance import graph, mutate
    if args.list:
        headers = mutate.library_headers(graph.ROOT / mutate.INC)
        for m in mutate.MUTANTS:
            at = mutate.locate(mutate.headers_for(m.kind, headers), m)
            where = at if isinstance(at, str) else at[3]
            print(f"{m.name:38} {m.kind:8} {where:34} {m.what}")
        return 0
    if args.sample < 1:
        print(f"ev3-conformance mutate: --sample {args.sample}: a whole number >= 1")
        return 2
    t0 = time.monotonic()
    try:
        res = mutate.run(graph.ROOT, args.only, jobs=args.jobs, limit=args.limit, sample=args.sample)
    except RuntimeError as e:
        print(f"mutate: {e}")
        return 2
    caught, counted = mutate.score(res)
    surv = [o for o in res if o.status == "survived"]
    timed = [o for o in res if o.status == "timeout"]
    other = [o for o in res if o.status not in ("caught", "survived", "timeout")]
    per = [o.seconds for o in res if o.status in ("caught", "survived", "timeout")]
    print(f"mutation score: {caught}/{counted} caught ({100.0 * caught / max(1, counted):.1f}%); "
          f"{len(timed)} without a verdict (timed out: not caught); "
          f"{len(other)} not counted (stale/equivalent/build-failed); "
          f"{sum(per) / max(1, len(per)):.0f}s per mutant on average, {time.monotonic() - t0:.0f}s in all")
    for o in surv:
        print(f"SURVIVED {o.mutant.name}: {o.mutant.what} ({o.detail})")
    for o in timed:
        print(f"TIMEOUT {o.mutant.name}: {o.mutant.what} (no check named a difference: {o.detail})")
    for o in other:
        print(f"{o.status.upper()} {o.mutant.name}: {o.detail[:300]}")
    return 0 if counted and caught * 100 >= args.min_score * counted else 1


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ev3-conformance", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    codec = sub.add_parser("codec", help="the reference codec of wire format v2")
    modes = codec.add_subparsers(dest="mode", required=True)

    dec = modes.add_parser("decode", help="decode one datagram")
    dec.add_argument("datagram", help="the datagram in hex (or as text with --text)")
    dec.add_argument("--text", action="store_true", help="the datagram is given as text")
    dec.set_defaults(run=_cmd_decode)

    enc = modes.add_parser("encode", help="encode one message")
    enc.add_argument("sender", type=int)
    enc.add_argument("receiver", type=int)
    enc.add_argument("msgid", type=int)
    enc.add_argument("type", type=int)
    enc.add_argument("params", nargs="*")
    enc.add_argument("--hex", action="store_true", help="params are hex ('-' for empty)")
    enc.set_defaults(run=_cmd_encode)

    gp = sub.add_parser("graph", help="TLC's state graph of a model and its edge-covering paths")
    gp.add_argument("--model", choices=sorted(MODELS), default="agent")
    gp.set_defaults(run=_cmd_graph)

    rp = sub.add_parser("replay", help="replay every edge of the model's state graph against a driver")
    rp.add_argument("--model", choices=sorted(MODELS) + ["fleet", "reports"], default="agent")
    rp.add_argument("--driver", help="driver command line (default: $EV3_BIN/ev3-agent --driver, ev3-master --driver, "
                                     "ev3-reports-driver)")
    rp.add_argument("--sample", type=int, default=1, metavar="N",
                    help="agent: replay one in N of the edges where the agent ignores a datagram or"
                         " answers a duplicate, and one of each class of them (default 1: all)")
    rp.add_argument("--seed", type=int, default=1, help="fleet: TLC -seed of the simulation (default 1)")
    rp.add_argument("--num", type=int, default=30, help="fleet: traces to simulate and replay (default 30; 0: none)")
    rp.add_argument("--depth", type=int, default=300, help="fleet: states per trace (TLC -depth, default 300)")
    rp.add_argument("--cfg", default="MCFleetSim.cfg", help="fleet: the simulation's cfg (spec/tla/ or a path)")
    rp.add_argument("--election-num", type=int, default=40,
                    help="fleet: traces of the whole system (MCSystemSim: the election) to simulate and replay "
                         "after the fleet's (default 40; 0: none)")
    rp.add_argument("--election-depth", type=int, default=150,
                    help="fleet: states per trace of the whole system (default 150)")
    rp.add_argument("--election-cfg", default="MCSystemSim.cfg",
                    help="fleet: the whole system's simulation cfg (spec/tla/ or a path)")
    rp.add_argument("--agent-driver", help="fleet: agent driver command line (default: --driver, else ev3-agent --driver)")
    rp.add_argument("--master-driver", help="fleet: master driver command line (default: ev3-master --driver)")
    rp.add_argument("--known", action="append", choices=["pending-resend"],
                    help="master: let a known, reported spec/core difference pass (counted and printed)")
    rp.set_defaults(run=_cmd_replay)

    vp = sub.add_parser("validate", help="check NDJSON traces of the programs against the spec (TLC)")
    vp.add_argument("traces", nargs="+", help="NDJSON trace files (--trace FILE of the programs)")
    vp.add_argument("--heartbeat", type=int, default=100, help="the run's --heartbeat-ms (TPing)")
    vp.add_argument("--loss", type=int, default=0, help="the run's --master-timeout-ms (TLoss; default 8 x heartbeat)")
    vp.add_argument("--paused", type=int, default=0, help="the run's --paused-timeout-ms (default: 2 x --loss when given, else 10 x heartbeat)")
    vp.add_argument("--sync", type=int, default=10000, help="the run's --sync-timeout-ms (TSync)")
    vp.add_argument("--window", type=int, default=0, help="dedupe window entries (default 50)")
    vp.add_argument("--jobs", type=int, default=2, help="TLC runs in parallel (default 2)")
    vp.add_argument("--election", action=argparse.BooleanOptionalAction, default=None,
                    help="check as an --election agent (AgentLogic + Election.tla, per agent); default: "
                         "when the trace has Election actions or variables")
    vp.add_argument("--score", type=int, default=None,
                    help="election: the agent's --score (default unknown: both outcomes of a comparison)")
    vp.add_argument("--epoch", type=int, default=1, help="election: the epoch its --state-dir started from")
    vp.add_argument("--voted-for", type=int, default=0, help="election: the vote its --state-dir started from")
    vp.add_argument("--master", action="store_true",
                    help="master traces against MasterLogic: ev3-master --driver --trace, or ev3-master "
                         "--trace over UDP (give its --agent-timeout-ms as --drop, --resend-ms as --resend)")
    vp.add_argument("--drop", type=int, default=4, help="--master: the run's drop timeout in ms (TDrop)")
    vp.add_argument("--resend", type=int, default=1,
                    help="--master: the run's resend period in ms (default 1: the driver's; ev3-master: 500)")
    vp.add_argument("--max-resends", type=int, default=10, help="--master: the run's max resends")
    vp.add_argument("--next-id", type=int, default=2,
                    help="--master: the first id the master hands out (a restart from --state-file: its next_id)")
    vp.add_argument("--first-msgid", type=int, default=None,
                    help="--master: the master's first msgid (default: the trace's msgid_from of its first "
                         "sending record; a restart from --state-file: its next_msgid)")
    vp.add_argument("--behaviour", action="append", help="--master: behaviour names (default wait)")
    vp.add_argument("--members", default="",
                    help="--master --election: the members (comma-separated ids) of the --state-file it "
                         "restarted from; with --candidate, and --epoch the file's epoch")
    vp.add_argument("--candidate", action="store_true",
                    help="--master --election: restarted from a --state-file, it starts as a CANDIDATE")
    vp.set_defaults(run=_cmd_validate)

    gm = sub.add_parser("merged", help="the traces of one run merged (happens-before) and checked against "
                                       "System.tla's and Election.tla's invariants")
    gm.add_argument("traces", nargs="+", help="NDJSON trace files of one run, or directories holding them")
    gm.add_argument("--epoch", action="append", metavar="FILE:NODE=E",
                    help="a node's epoch before its first record when not 1 (a --state-dir / --state-file "
                         "it restarted from), e.g. master2.ndjson:master=2")
    gm.add_argument("--master-timeout-ms", type=int, metavar="MS", dest="loss",
                    help="the agents' heartbeat timeout, as given to ev3-agent (System's T for "
                         "NoUnsupervisedMotionInv); default: ev3-agent's (800)")
    gm.set_defaults(run=_cmd_merged)

    mp = sub.add_parser("mutate", help="seeded faults in a copy of the core, each checked by replay/validate")
    mp.add_argument("--only", nargs="*", help="mutant names (prefixes, e.g. A01 M)")
    mp.add_argument("--list", action="store_true", help="list the mutants and exit")
    mp.add_argument("--sample", type=int, default=1, metavar="N",
                    help="the agent replay as `replay --model agent --sample N` (default 1: every edge)")
    mp.add_argument("--jobs", type=int, default=2, help="ninja jobs (default 2)")
    mp.add_argument("--limit", type=float, default=120.0, help="CPU seconds of a driver before it is killed")
    mp.add_argument("--min-score", type=float, default=95.0, help="exit 1 below this score in %% (default 95)")
    mp.set_defaults(run=_cmd_mutate)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    return args.run(args)


if __name__ == "__main__":
    sys.exit(main())
