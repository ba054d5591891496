// Built with -fno-exceptions -fno-rtti (as the agent core is): the library must compile and work so.
// The codec must also allocate nothing: this program replaces the global operator new and counts.
// A plain program, not GoogleTest; it exits non-zero on the first failed check.
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>
#include <string_view>

#include "ev3proto/dedupe.hpp"
#include "ev3proto/messages.hpp"
#include "ev3proto/wire.hpp"

#include "../firmware_check.hpp"

namespace {
long g_news = 0;  // single-threaded: a plain counter
}  // namespace

// Not inlined: GCC would otherwise see free() of what operator new returned and warn
// (mismatched-new-delete).
__attribute__((noinline)) void* operator new(std::size_t n) {
  ++g_news;
  void* p = std::malloc(n ? n : 1);
  if (p == nullptr) std::abort();
  return p;
}
__attribute__((noinline)) void operator delete(void* p) noexcept { std::free(p); }
__attribute__((noinline)) void operator delete(void* p, std::size_t) noexcept { std::free(p); }

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

  // No heap: decode and encode of accepted and rejected datagrams, escapes, the longest datagram.
  static char big[kMaxDatagram];
  std::memcpy(big, "1:2:3:7:", 8);
  for (std::size_t i = 8; i < sizeof big; ++i) big[i] = (i % 3 == 0) ? ':' : 'a';
  const std::string_view datagrams[] = {"7:1:12:5:WORKING", "7:1:4711:18:in1:COL-REFLECT:42:17:3",
                                        "1:2:3:7:a%3Ab:%25%00%FF:", "1:2:3:7:%3a", "1:2:3:5:IDLE:\x01",
                                        "x", std::string_view(big, sizeof big)};
  const long before = g_news;
  char out[kMaxDatagram];
  for (const std::string_view d : datagrams) {
    if (decode(d, m).ok()) CHECK(encode(m, out, sizeof out).ok());
  }
  CHECK(g_news == before);
  void* probe = ::operator new(8);  // the counter itself works
  ::operator delete(probe);
  CHECK(g_news == before + 1);

  DedupeWindow<> w;
  CHECK(w.first_time(7, 12));
  CHECK(!w.first_time(7, 12));
  std::puts("no-exceptions/no-rtti build: ok");
  return 0;
}
