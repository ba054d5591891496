// Built with -fno-exceptions -fno-rtti (as the agent is) and with the global operator new replaced by
// one that aborts: parsing, checking, printing and drawing the built-ins and refusing bad definitions
// must compile so and allocate nothing on the heap. A plain program (no gtest), also run under qemu-arm.
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>

#include "ev3proto/behaviour/automaton.hpp"
#include "ev3proto/behaviour/builtins.hpp"
#include "ev3proto/behaviour/checker.hpp"
#include "ev3proto/behaviour/dot.hpp"
#include "ev3proto/behaviour/parser.hpp"
#include "ev3proto/behaviour/print.hpp"

#include "../firmware_check.hpp"

namespace {
[[noreturn]] void heap_used() {
  std::fputs("no_heap: the behaviour code allocated on the heap\n", stderr);
  std::abort();
}
}  // namespace

void* operator new(std::size_t) { heap_used(); }
void* operator new[](std::size_t) { heap_used(); }
void* operator new(std::size_t, const std::nothrow_t&) noexcept { heap_used(); }
void* operator new[](std::size_t, const std::nothrow_t&) noexcept { heap_used(); }
void operator delete(void*) noexcept {}
void operator delete[](void*) noexcept {}
void operator delete(void*, std::size_t) noexcept {}
void operator delete[](void*, std::size_t) noexcept {}

using namespace ev3proto::behaviour;

static Definition def, again;
static char buf[1 << 14];

int main() {
  Diagnostic d;
  Findings f;
  for (const Builtin& b : kBuiltins) {
    CHECK(parse(b.text, def, d));
    CHECK(check(def, kModelA, f));
    Text c(buf, sizeof buf);
    compact(c, def);
    CHECK(!c.overflow());
    CHECK(parse(c.view(), again, d));
    CHECK(equivalent(def, again));
    Text g(buf, sizeof buf);
    to_dot(g, def);
    CHECK(!g.overflow());
  }
  // Refusals: a syntax error, a meaning error, a checker finding, a bad argument.
  CHECK(!parse("behaviour x\nstate a = pause 1s ->", def, d));
  CHECK(d.code == Code::syntax && d.pos.line == 2 && d.pos.col == 22);
  CHECK(!parse("behaviour x\nstate a = trun 90 -> a", def, d));
  CHECK(std::strcmp(d.text, "unknown action 'trun' (actions: run, drive, turn, stop, pause, wait, repeat)") == 0);
  CHECK(parse("behaviour x;state a = wait 1s -> b;state b = wait 1s -> a", def, d));
  CHECK(!check(def, kModelA, f) && f.items[0].code == Code::no_stop);
  CHECK(parse(find_builtin("explore")->text, def, d));
  const std::string_view args[] = {"speed=2000"};
  CHECK(apply_args(def, args, 1, d));
  CHECK(!check(def, kModelA, f) && f.items[0].code == Code::range);
  const std::string_view bad[] = {"speed"};
  CHECK(!apply_args(def, bad, 1, d));
  // The automaton runs explore: forward, a bump, its reaction, a pause and resume, its reports
  // (distance, colour).
  CHECK(parse(find_builtin("explore")->text, def, d));
  static Automaton a;
  const std::uint8_t ports[kSensorCount] = {8, 1, 4, 0};
  a.load(def, ports);
  a.start(0);
  CHECK(a.event(EventKind::OBSTACLE_DETECTED));
  a.finished();
  a.pause();
  a.resume(10);
  const Reading none[kSensorCount] = {};
  a.tick(1010, none);
  Output o;
  int reports = 0, starts = 0;
  while (a.poll(o)) {
    reports += o.kind == Output::Kind::report ? 1 : 0;
    starts += o.kind == Output::Kind::start ? 1 : 0;
  }
  CHECK(reports == 2 && starts == 3 && a.state() == def.find_state("backoff"));
  std::puts("no_heap: ok");
  return 0;
}
