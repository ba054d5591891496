// libFuzzer target: the behaviour language's parser and checker on any bytes (as a robot gets them
// in BEHAVIOUR custom). A refusal must name a place inside the text; an accepted definition must be
// checked, drawn and written compact without overflowing, and its compact form must parse back to
// the same tables, also after BEHAVIOUR arguments. Any violation traps. Also linked with
// replay_main.cpp to run the committed corpus under gcc/armel.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "ev3proto/behaviour/checker.hpp"
#include "ev3proto/behaviour/dot.hpp"
#include "ev3proto/behaviour/parser.hpp"
#include "ev3proto/behaviour/print.hpp"

namespace {

using namespace ev3proto::behaviour;

[[noreturn]] void violation() { __builtin_trap(); }

// static: a Definition is a few KiB; keep them off the fuzzer's stack.
Definition def, again;
char text_buf[1 << 14];
char dot_buf[1 << 16];

// The place of a refusal is in the text: a line it has, a column at most one past that line's end.
bool place_inside(std::string_view text, const Diagnostic& d) {
  if (d.len == 0 || d.len > kMaxMessage) return false;
  if (d.pos.line == 0) return d.code == Code::limit || d.code == Code::meaning;  // size, or an argument
  std::size_t line = 1, start = 0;
  for (std::size_t i = 0; i < text.size() && line < d.pos.line; ++i)
    if (text[i] == '\n') {
      ++line;
      start = i + 1;
    }
  if (line != d.pos.line || d.pos.col == 0) return false;
  std::size_t end = start;
  while (end < text.size() && text[end] != '\n') ++end;
  return d.pos.col <= end - start + 1;
}

void round_trip(std::string_view text) {
  Diagnostic d;
  Findings f;
  check(def, kModelA, f);
  for (std::uint8_t k = 0; k < f.count; ++k)
    if (!place_inside(text, f.items[k]) && f.items[k].pos.line != 0) violation();
  check(def, kModelA, kModelA.devices & ~role_bit(Role::touch), f);
  Text c(text_buf, sizeof text_buf);
  compact(c, def);
  if (c.overflow()) violation();
  if (!parse(c.view(), again, d) || !equivalent(def, again)) violation();
  Text g(dot_buf, sizeof dot_buf);
  to_dot(g, def);
  if (g.overflow()) violation();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  Diagnostic d;
  if (!parse(text, def, d)) {
    if (!place_inside(text, d)) violation();
    return 0;
  }
  round_trip(text);
  // BEHAVIOUR arguments over the params: a refusal leaves the tables usable, an acceptance too.
  const std::string_view args[] = {"speed=2000", "seed=7", "angle=random 1..2", "colour=blue", "settle=0.5"};
  for (const std::string_view& a : args)
    if (apply_args(def, &a, 1, d)) round_trip(text);
  return 0;
}
