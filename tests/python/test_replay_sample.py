"""The sampled agent replay (make conformance: `replay --model agent --sample 8`): which edges it
leaves out, and that the walk still reaches every state and replays every other edge."""

import pytest

from ev3conformance import graph as gr
from ev3conformance import replay


def state(st: str, name: str, msg: dict | None = None, win=()) -> dict:
    return {"ag": {"id": 2, "state": st, "win": win},
            "lastAction": {"name": name, "args": (msg,) if msg else ()}, "out": ()}


def msg(mid: int, src: int = 1, type_: str = "START") -> dict:
    return {"args": (), "type": type_, "src": src, "dst": 2, "msgid": mid, "ref": 0}


def fan(ignored: int, order=None) -> gr.Graph:
    """Init -RecvMaster-> a -RecvStart-> b; from a: @p ignored Ignore edges (msgid 10, 11, ...
    from sender 1, each to a state of its own), plus one from sender 3; edges in @p order."""
    g = gr.Graph()
    win = ({"src": 1, "msgid": 1},)
    g.states = {"i": state("IDLE", "Init"), "a": state("ACTIVE", "RecvMaster", msg(1, type_="MASTER"), win),
                "b": state("WORKING", "RecvStart", msg(2), win)}
    edges = [("i", "a"), ("a", "b")]
    for k in range(ignored):
        g.states[f"x{k}"] = state("ACTIVE", "Ignore", msg(10 + k), win)
        edges.append(("a", f"x{k}"))
    g.states["y"] = state("ACTIVE", "Ignore", msg(5, src=3), win)
    edges.append(("a", "y"))
    for k in order or range(len(edges)):
        g.edges.append(edges[k])
    for ei, (u, _) in enumerate(g.edges):
        g.out.setdefault(u, []).append(ei)
    g.init = ["i"]
    return g


def kept(g: gr.Graph, every: int) -> set[tuple[str, str]]:
    leave = replay.sample_leaves(g, every)
    return {g.edges[ei] for ei in range(len(g.edges)) if ei not in leave}


def test_every_edge_without_a_sample():
    g = fan(50)
    assert replay.sample_leaves(g, 1) == set()


def test_the_sample_keeps_state_changes_one_per_class_and_about_one_in_n():
    g = fan(400)
    k = kept(g, 8)
    assert ("i", "a") in k and ("a", "b") in k          # not Ignore/RecvDuplicate: always
    assert ("a", "y") in k                              # the only one of its class (sender 3)
    ignored = [e for e in k if e[1].startswith("x")]
    assert 1 <= len(ignored) < 400
    assert 20 <= len(ignored) <= 90, len(ignored)       # about 400 / 8


def test_the_sample_is_a_function_of_the_graph_not_of_its_order():
    g = fan(100)
    order = list(range(len(g.edges)))[::-1]
    assert kept(g, 8) == kept(fan(100, order), 8)


def test_msgid_against_the_window():
    win = ({"src": 1, "msgid": 4},)
    assert replay.msgid_relation(msg(4), win) == "in"
    assert replay.msgid_relation(msg(3), win) == "below"
    assert replay.msgid_relation(msg(5), win) == "above"
    assert replay.msgid_relation(msg(5, src=3), win) == "none"


def test_the_walk_reaches_every_state_through_a_left_out_tree_edge():
    # Init -Ignore-> z (the only way to z) -RecvStart-> w: the tree edge into z is replayed even
    # when the sample leaves it out, a leaf edge it leaves out is not.
    g = gr.Graph()
    g.states = {"i": state("IDLE", "Init"), "z": state("IDLE", "Ignore", msg(3)),
                "w": state("WORKING", "RecvStart", msg(4)), "l": state("IDLE", "Ignore", msg(5))}
    g.edges = [("i", "z"), ("z", "w"), ("i", "l")]
    g.out = {"i": [0, 2], "z": [1]}
    g.init = ["i"]
    ps = gr.cover(g)
    ops = list(gr.walk(g, ps, leave={0, 2}.__contains__))
    assert [op for op in ops if op[0] == "edge"] == [("edge", 0), ("edge", 1)]


def test_a_dump_recorded_for_the_same_spec_is_reused_and_a_changed_spec_runs_tlc(tmp_path, monkeypatch):
    spec, build = tmp_path / "spec", tmp_path / "build"
    spec.mkdir()
    (spec / "M.tla").write_text("---- MODULE M ----\n====\n")
    (spec / "M.cfg").write_text("INIT Init\n")
    monkeypatch.setattr(gr, "BUILD", build)
    ran = []
    monkeypatch.setattr(gr, "tlc", lambda *a, **k: (ran.append(a), (1, "exit 1"))[1])
    gr.dump_args("m")
    (build / "m-graph.dot").write_text('1 [label="/\\\\ x = 1",style = filled]\n')
    gr.record_dump("M", "M.cfg", "m", "7 states generated, 1 distinct states found, 0 states left", cwd=spec)
    g, figs = gr.dump_graph("M.tla", "M.cfg", "m", cwd=spec)
    assert figs["reused"] and figs["distinct"] == 1 and g.init == ["1"] and not ran
    (spec / "M.tla").write_text("---- MODULE M ----\nx == 1\n====\n")     # the spec changed
    with pytest.raises(RuntimeError, match="TLC failed"):
        gr.dump_graph("M.tla", "M.cfg", "m", cwd=spec)
    assert ran and not (build / "m-graph.key").exists()
