"""Every code mutant of `ev3-conformance mutate` (ev3conformance/mutate.py) is sited in the library as
it is: its text occurs exactly once in the function it names. A mutant whose text the code no longer
has would be reported as not applied by `make mutate`, long after the change that lost it; this test
(no compiler, no TLC) names it at once."""

from ev3conformance import graph, mutate


def test_every_mutant_locates_exactly_once():
    headers = mutate.library_headers(graph.ROOT / mutate.INC)
    lost = []
    for m in mutate.MUTANTS:
        at = mutate.locate(mutate.headers_for(m.kind, headers), m)
        if isinstance(at, str):
            lost.append(f"{m.name}: {at}")
    assert not lost, "mutants the library no longer has:\n" + "\n".join(lost)
