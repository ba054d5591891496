// Google Benchmark: libev3proto's decode/encode against (a) a decoder/encoder written the way the
// thesis did it (std::string, std::getline on ':', std::stoi, std::vector<std::string>) and (b) the
// floor: a memchr-only scan that just finds the separators of the same bytes (and, for encode, a
// plain memcpy of the finished datagram). Heap allocations per operation are counted by replacing
// the global operator new in this binary. And, to put the decode into proportion, the receive
// system call that comes before it in the master: recvfrom() of a PING queued on a loopback UDP
// socket; and what signed mode adds: checking and sealing a signed PING. docs/benchmarks.md records
// the figures (`make bench`).
#include <benchmark/benchmark.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <new>
#include <sstream>
#include <string>
#include <vector>

#include "ev3proto/auth.hpp"
#include "ev3proto/wire.hpp"

// ---- allocation counter ---------------------------------------------------------------------------
namespace {
std::size_t g_allocations = 0;  // single-threaded benchmarks: a plain counter is enough
}  // namespace

void* operator new(std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace {

// ---- the datagrams --------------------------------------------------------------------------------
std::string ping() { return "7:1:12:5:WORKING"; }
std::string sensor_value() { return "7:1:4711:18:in1:COL-REFLECT:42:17:3"; }
// ~1 kB BEHAVIOUR: a name and 31 key=value arguments, a few of them with escapes.
std::string behaviour() {
  std::string d = "1:7:123456:7:follow_line";
  for (int i = 0; i < 31; ++i) {
    d += ":param_" + std::to_string(i) + "=value_" + std::to_string(i * 7919);
    if (i % 8 == 3) d += "%3A50%25";
    d += "_xxxxxxxxxx";
  }
  return d;
}

const std::string& datagram(int which) {
  static const std::string all[3] = {ping(), sensor_value(), behaviour()};
  return all[which];
}
const char* const kNames[3] = {"ping", "sensor_value", "behaviour_1k"};

// ---- (a) the thesis-style decoder and encoder ------------------------------------------------------
struct ThesisMessage {
  int sender = 0, receiver = 0, type = 0;
  long msgid = 0;
  std::vector<std::string> params;
};

bool thesis_decode(const std::string& datagram, ThesisMessage& m) {
  std::vector<std::string> fields;
  std::stringstream ss(datagram);
  std::string item;
  while (std::getline(ss, item, ':')) fields.push_back(item);
  if (fields.size() < 4) return false;
  m.sender = std::stoi(fields[0]);
  m.receiver = std::stoi(fields[1]);
  m.msgid = std::stol(fields[2]);
  m.type = std::stoi(fields[3]);
  m.params.assign(fields.begin() + 4, fields.end());
  return true;
}

std::string thesis_encode(const ThesisMessage& m) {
  std::string out = std::to_string(m.sender) + ":" + std::to_string(m.receiver) + ":" +
                    std::to_string(m.msgid) + ":" + std::to_string(m.type);
  for (const std::string& p : m.params) out += ":" + p;
  return out;
}

// ---- (b) the floor: find the separators and nothing else ------------------------------------------
std::size_t memchr_scan(const char* p, std::size_t n, std::uint16_t* offsets) {
  std::size_t count = 0;
  const char* const begin = p;
  const char* const end = p + n;
  while (const void* hit = std::memchr(p, ':', static_cast<std::size_t>(end - p))) {
    const char* c = static_cast<const char*>(hit);
    offsets[count++ & 63u] = static_cast<std::uint16_t>(c - begin);
    p = c + 1;
  }
  return count;
}

// ---- (c) one plain pass: each byte looked at once -------------------------------------------------
// What a decoder written as one scalar loop must do at the least: copy each byte, note where each ':'
// is, and tell whether any byte is a '%' or lies outside 0x20..0x7E (no numbers, no unescaping). A
// table gives each byte's class, so that a plain byte costs one load and one well-predicted branch.
enum : unsigned char { kPlain = 0, kColon = 1, kPercent = 2, kOutOfRange = 4 };
struct ByteClasses {
  unsigned char of[256];
  constexpr ByteClasses() : of{} {
    for (int c = 0; c < 256; ++c)
      of[c] = c < 0x20 || c > 0x7E ? kOutOfRange : c == ':' ? kColon : c == '%' ? kPercent : kPlain;
  }
};
constexpr ByteClasses kByteClasses{};

// Returns the number of ':'; @p special gets the classes of the other special bytes ORed together.
std::size_t scalar_pass(const char* p, std::size_t n, char* dst, std::uint16_t* offsets, unsigned& special) {
  std::size_t count = 0;
  unsigned seen = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const unsigned char c = static_cast<unsigned char>(p[k]);
    dst[k] = static_cast<char>(c);
    const unsigned char cls = kByteClasses.of[c];
    if (cls == kColon) {
      offsets[count++ & 63u] = static_cast<std::uint16_t>(k);
    } else if (cls != kPlain) {
      seen |= cls;
    }
  }
  special = seen;
  return count;
}

void set_counters(benchmark::State& state, std::size_t allocations, std::size_t bytes) {
  state.counters["allocs/op"] =
      benchmark::Counter(static_cast<double>(allocations), benchmark::Counter::kAvgIterations);
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) * static_cast<std::int64_t>(bytes));
}

// ---- decode ---------------------------------------------------------------------------------------
void BM_Decode_Ours(benchmark::State& state) {
  const std::string& d = datagram(static_cast<int>(state.range(0)));
  state.SetLabel(kNames[state.range(0)]);
  static ev3proto::Message m;
  const std::size_t before = g_allocations;
  for (auto _ : state) {
    const char* p = d.data();
    benchmark::DoNotOptimize(p);
    const ev3proto::DecodeResult r = ev3proto::decode(std::string_view(p, d.size()), m);
    benchmark::DoNotOptimize(r);
    benchmark::ClobberMemory();
  }
  if (!ev3proto::decode(d, m).ok()) state.SkipWithError("datagram rejected");
  set_counters(state, g_allocations - before, d.size());
}

void BM_Decode_Thesis(benchmark::State& state) {
  const std::string& d = datagram(static_cast<int>(state.range(0)));
  state.SetLabel(kNames[state.range(0)]);
  ThesisMessage m;
  const std::size_t before = g_allocations;
  for (auto _ : state) {
    bool ok = thesis_decode(d, m);
    benchmark::DoNotOptimize(ok);
    benchmark::ClobberMemory();
  }
  set_counters(state, g_allocations - before, d.size());
}

void BM_Decode_MemchrFloor(benchmark::State& state) {
  const std::string& d = datagram(static_cast<int>(state.range(0)));
  state.SetLabel(kNames[state.range(0)]);
  std::uint16_t offsets[64];
  const std::size_t before = g_allocations;
  for (auto _ : state) {
    const char* p = d.data();
    benchmark::DoNotOptimize(p);
    std::size_t n = memchr_scan(p, d.size(), offsets);
    benchmark::DoNotOptimize(n);
    benchmark::DoNotOptimize(offsets);
    benchmark::ClobberMemory();
  }
  set_counters(state, g_allocations - before, d.size());
}

// (c): scalar_pass() over the whole datagram.
void BM_Decode_ScalarPassFloor(benchmark::State& state) {
  const std::string& d = datagram(static_cast<int>(state.range(0)));
  state.SetLabel(kNames[state.range(0)]);
  static char copy[ev3proto::kMaxDatagram];
  std::uint16_t offsets[64];
  const std::size_t before = g_allocations;
  for (auto _ : state) {
    const char* p = d.data();
    benchmark::DoNotOptimize(p);
    unsigned special = 0;
    std::size_t n = scalar_pass(p, d.size(), copy, offsets, special);
    benchmark::DoNotOptimize(n);
    benchmark::DoNotOptimize(special);
    benchmark::DoNotOptimize(offsets);
    benchmark::ClobberMemory();
  }
  set_counters(state, g_allocations - before, d.size());
}

// (d): the copy and range check that ours makes of the param region (detail::copy_printable, the
// loop the compiler vectorises), over the whole datagram, alone.
void BM_Decode_CopyCheckFloor(benchmark::State& state) {
  const std::string& d = datagram(static_cast<int>(state.range(0)));
  state.SetLabel(kNames[state.range(0)]);
  static char copy[ev3proto::kMaxDatagram];
  const std::size_t before = g_allocations;
  for (auto _ : state) {
    const char* p = d.data();
    benchmark::DoNotOptimize(p);
    bool printable = ev3proto::detail::copy_printable(p, p + d.size(), copy);
    benchmark::DoNotOptimize(printable);
    benchmark::ClobberMemory();
  }
  set_counters(state, g_allocations - before, d.size());
}

// ---- encode ---------------------------------------------------------------------------------------
void BM_Encode_Ours(benchmark::State& state) {
  const std::string& d = datagram(static_cast<int>(state.range(0)));
  state.SetLabel(kNames[state.range(0)]);
  static ev3proto::Message m;
  if (!ev3proto::decode(d, m).ok()) state.SkipWithError("datagram rejected");
  static char buf[ev3proto::kMaxDatagram];
  const std::size_t before = g_allocations;
  for (auto _ : state) {
    const ev3proto::EncodeResult e = ev3proto::encode(m, buf, sizeof buf);
    benchmark::DoNotOptimize(e);
    benchmark::ClobberMemory();
  }
  if (ev3proto::encode(m, buf, sizeof buf).size != d.size()) state.SkipWithError("not canonical");
  set_counters(state, g_allocations - before, d.size());
}

void BM_Encode_Thesis(benchmark::State& state) {
  const std::string& d = datagram(static_cast<int>(state.range(0)));
  state.SetLabel(kNames[state.range(0)]);
  ThesisMessage m;
  thesis_decode(d, m);
  const std::size_t before = g_allocations;
  for (auto _ : state) {
    std::string out = thesis_encode(m);
    benchmark::DoNotOptimize(out);
    benchmark::ClobberMemory();
  }
  set_counters(state, g_allocations - before, d.size());
}

void BM_Encode_MemcpyFloor(benchmark::State& state) {
  const std::string& d = datagram(static_cast<int>(state.range(0)));
  state.SetLabel(kNames[state.range(0)]);
  static char buf[ev3proto::kMaxDatagram];
  const std::size_t before = g_allocations;
  for (auto _ : state) {
    const char* p = d.data();
    benchmark::DoNotOptimize(p);
    std::memcpy(buf, p, d.size());
    benchmark::ClobberMemory();
  }
  set_counters(state, g_allocations - before, d.size());
}

// ---- the receive system call ------------------------------------------------------------------------
// recvfrom() as io/udp.cpp calls it (a 4097-byte buffer, MSG_TRUNC, the sender's address), on a
// loopback UDP socket whose queue holds the datagrams already: each iteration sends kBatch copies of
// the PING (not measured), then receives them; the counters are the receiving thread's CPU time
// (CLOCK_THREAD_CPUTIME_ID: user and kernel; the two clock reads per batch add under 10 ns to each)
// and wall time per recvfrom(). The receive buffer is asked for 1 MiB; kBatch small datagrams need
// about 1 KiB of it each. A datagram lost on the way fails the benchmark.
constexpr int kBatch = 128;

double thread_cpu_ns() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e9 + static_cast<double>(t.tv_nsec);
}

double wall_ns() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return static_cast<double>(t.tv_sec) * 1e9 + static_cast<double>(t.tv_nsec);
}

void BM_Recvfrom_Loopback(benchmark::State& state) {
  const std::string& d = datagram(0);
  state.SetLabel("ping");
  const int rx = socket(AF_INET, SOCK_DGRAM, 0);
  const int tx = socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t alen = sizeof addr;
  const int rcvbuf = 1 << 20;
  if (rx < 0 || tx < 0 || setsockopt(rx, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf) != 0 || bind(rx, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 ||
      getsockname(rx, reinterpret_cast<sockaddr*>(&addr), &alen) != 0 ||
      connect(tx, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    state.SkipWithError(std::strerror(errno));
    return;
  }
  std::vector<char> buf(ev3proto::kMaxDatagram + 1);
  double cpu = 0, wall = 0;
  std::size_t received = 0;
  for (auto _ : state) {
    for (int k = 0; k < kBatch; ++k)
      if (send(tx, d.data(), d.size(), 0) != static_cast<ssize_t>(d.size())) state.SkipWithError("send failed");
    const double c0 = thread_cpu_ns(), w0 = wall_ns();
    for (int k = 0; k < kBatch; ++k) {
      sockaddr_in from{};
      socklen_t flen = sizeof from;
      const ssize_t n = recvfrom(rx, buf.data(), buf.size(), MSG_TRUNC | MSG_DONTWAIT,
                                 reinterpret_cast<sockaddr*>(&from), &flen);
      received += n == static_cast<ssize_t>(d.size());
    }
    cpu += thread_cpu_ns() - c0;
    wall += wall_ns() - w0;
  }
  if (received != state.iterations() * kBatch) state.SkipWithError("a datagram was not received");
  close(rx);
  close(tx);
  const double n = static_cast<double>(state.iterations()) * kBatch;
  state.counters["recvfrom_cpu_ns"] = cpu / n;
  state.counters["recvfrom_wall_ns"] = wall / n;
}

}  // namespace

// ---- signed mode ---------------------------------------------------------------------------------
// What signed mode adds per datagram (docs/protocol.md "Signed datagrams"): the receiver's check of
// a signed PING (its tag computed and compared; the window: the first run takes the counter, every
// later one is a replay, found after the same tag check), and the sender's trailer.
const ev3proto::auth::Key& bench_key() {
  static const ev3proto::auth::Key k = [] {
    ev3proto::auth::Key key;
    if (sodium_init() < 0 || ev3proto::auth::Key::parse(std::string(64, 'A'), key) != nullptr) std::abort();
    return key;
  }();
  return k;
}

void BM_Auth_Open(benchmark::State& state) {
  const std::string& d = datagram(0);
  state.SetLabel("ping, signed");
  ev3proto::auth::Signer s(bench_key(), 1);
  char t[ev3proto::auth::kTrailer];
  s.seal(d, t);
  const std::string signed_ping = d + std::string(t, sizeof t);
  static ev3proto::auth::Verifier<16> v(bench_key());
  for (auto _ : state) {
    std::string_view out;
    benchmark::DoNotOptimize(v.open(signed_ping, out));
    benchmark::ClobberMemory();
  }
  set_counters(state, 0, signed_ping.size());
}

void BM_Auth_Seal(benchmark::State& state) {
  const std::string& d = datagram(0);
  state.SetLabel("ping");
  ev3proto::auth::Signer s(bench_key(), 1);
  char t[ev3proto::auth::kTrailer];
  for (auto _ : state) {
    s.seal(d, t);
    benchmark::DoNotOptimize(t);
    benchmark::ClobberMemory();
  }
  set_counters(state, 0, d.size());
}

BENCHMARK(BM_Decode_Ours)->DenseRange(0, 2);
BENCHMARK(BM_Decode_Thesis)->DenseRange(0, 2);
BENCHMARK(BM_Decode_MemchrFloor)->DenseRange(0, 2);
BENCHMARK(BM_Decode_ScalarPassFloor)->DenseRange(0, 2);
BENCHMARK(BM_Decode_CopyCheckFloor)->DenseRange(0, 2);
BENCHMARK(BM_Encode_Ours)->DenseRange(0, 2);
BENCHMARK(BM_Encode_Thesis)->DenseRange(0, 2);
BENCHMARK(BM_Encode_MemcpyFloor)->DenseRange(0, 2);
BENCHMARK(BM_Recvfrom_Loopback);
BENCHMARK(BM_Auth_Open);
BENCHMARK(BM_Auth_Seal);

BENCHMARK_MAIN();
