// Google Benchmark: libev3proto's decode/encode against (a) a decoder/encoder written the way the
// thesis did it (std::string, std::getline on ':', std::stoi, std::vector<std::string>) and (b) the
// floor: a memchr-only scan that just finds the separators of the same bytes (and, for encode, a
// plain memcpy of the finished datagram). Heap allocations per operation are counted by replacing
// the global operator new in this binary. docs/benchmarks.md records the figures (`make bench`).
#include <benchmark/benchmark.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <new>
#include <sstream>
#include <string>
#include <vector>

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

}  // namespace

BENCHMARK(BM_Decode_Ours)->DenseRange(0, 2);
BENCHMARK(BM_Decode_Thesis)->DenseRange(0, 2);
BENCHMARK(BM_Decode_MemchrFloor)->DenseRange(0, 2);
BENCHMARK(BM_Encode_Ours)->DenseRange(0, 2);
BENCHMARK(BM_Encode_Thesis)->DenseRange(0, 2);
BENCHMARK(BM_Encode_MemcpyFloor)->DenseRange(0, 2);

BENCHMARK_MAIN();
