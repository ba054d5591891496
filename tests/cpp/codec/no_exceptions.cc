// Built with -fno-exceptions -fno-rtti (as the agent core is): the library must compile and work so.
// A plain program, not GoogleTest; it exits non-zero on the first failed check.
#include <cstdio>
#include <cstring>

#include "ev3proto/dedupe.hpp"
#include "ev3proto/messages.hpp"
#include "ev3proto/wire.hpp"

#if defined(__cpp_exceptions) || defined(__EXCEPTIONS)
#error "this file must be compiled with -fno-exceptions"
#endif
#if defined(__cpp_rtti) || defined(__GXX_RTTI)
#error "this file must be compiled with -fno-rtti"
#endif

#define CHECK(cond)                                                    \
  do {                                                                 \
    if (!(cond)) {                                                     \
      std::fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond); \
      return 1;                                                        \
    }                                                                  \
  } while (0)

int main() {
  using namespace ev3proto;
  Message m;
  CHECK(decode("7:1:12:5:WORKING", m).ok());
  CHECK(m.param_state(0) == AgentState::WORKING);
  char buf[64];
  const EncodeResult e = encode(m, buf, sizeof buf);
  CHECK(e.ok() && e.size == 16 && std::memcmp(buf, "7:1:12:5:WORKING", 16) == 0);
  const DecodeResult r = decode("1:2:3:7:%41", m);
  CHECK(r.reason == Reason::bad_escape && r.field == 4);
  CHECK(to_string(r.reason) == "bad escape");
  DedupeWindow<> w;
  CHECK(w.first_time(7, 12));
  CHECK(!w.first_time(7, 12));
  std::puts("no-exceptions/no-rtti build: ok");
  return 0;
}
