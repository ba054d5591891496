// The master core's CPU per datagram at one datagram rate with 100 and with 10,000 registered agents
// (the target: within 1.5x). docs/benchmarks.md, "Master at scale", has the figures and the command.
//
// Before the timed loop: N agents sync (AGENT, MASTER, ACK) and report ACTIVE once; 100 of them get a
// BEHAVIOUR they never answer, so 100 commands are always pending (resent every 500 ms, failed after
// 10 resends and given again), and every entry has its drop deadline armed. Timed: PINGs round robin
// at 10,000 datagrams per second of the core's clock (each of 100 agents pings every 10 ms, each of
// 10,000 every second), as a program feeds them: handle_datagram (which first acts on the deadlines
// due: resends, failures), its PONG and resends drained, the operator events drained, then
// next_deadline() for the loop's sleep. The same source builds against an earlier commit's headers
// (bench_master_baseline, EV3_MASTER_BASELINE) to show the registry walk it replaced.
// BM_MasterReport: the same fleet reporting instead (docs/reports.md): REPORTs round robin at the
// same rate, each the next number of its agent, recorded (PCTake) and acknowledged (PCAck); not in
// the baseline, whose headers predate them.
// BM_MasterPingElection: BM_MasterPing with the election on (the PC's membership of the first 30
// agents, one per epoch as they sync; LEADER every 100 ms; commands in EPOCH_CMD); not in the baseline.
#include <benchmark/benchmark.h>

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include <ev3proto/master.hpp>

namespace {

using namespace ev3proto;

constexpr std::uint64_t kDatagramsPerSecond = 10000;
constexpr std::size_t kPending = 100;  // agents with a command that is never answered

std::size_t drain(Master<>& m, std::vector<std::uint16_t>* timed_out) {
  std::size_t n = 0;
  MasterTransmit t;
  while (m.poll_transmit(t)) ++n;
  OperatorEvent e;
  while (m.poll_event(e))
    if (timed_out != nullptr && e.kind == OperatorEvent::Kind::timed_out) timed_out->push_back(e.agent);
  return n;
}

/// The timed part: one PING as a program feeds it (a function of its own, for profilers).
struct Feed {
  Master<>& m;
  std::vector<std::uint32_t>& msgid;
  const Command& behaviour;
  Millis t0;
  std::uint64_t k = 0, sent = 0;
  Millis now = 0;
  std::vector<std::uint16_t> timed_out;

  __attribute__((noinline)) void step() {
    const std::size_t n = msgid.size();
    const std::size_t i = k % n;
    char buf[64];
    now = t0 + 1 + k * 1000 / kDatagramsPerSecond;
    std::snprintf(buf, sizeof buf, "%zu:1:%u:5:ACTIVE", 2 + i, ++msgid[i]);
    m.handle_datagram(buf, static_cast<Peer>(i + 1), now);
    sent += drain(m, &timed_out);
    for (std::uint16_t a : timed_out) m.command(a, behaviour, now);  // keep 100 commands pending
    if (!timed_out.empty()) sent += drain(m, nullptr);
    timed_out.clear();
    benchmark::DoNotOptimize(m.next_deadline());
    ++k;
  }
};

#ifndef EV3_BENCH_BASELINE
/// With the election on, the PC adds each agent that syncs to its membership (up to kMaxMembership),
/// one per epoch: it stands (ELECT) and the members of the list it counts against vote for it.
void elect(Master<>& m, std::vector<std::uint32_t>& msgid, Millis now) {
  char buf[64];
  for (int round = 0; round < 4 && m.role() == MasterRole::candidate; ++round) {
    for (std::uint16_t id : m.members()) {
      const std::size_t i = id - 2;
      std::snprintf(buf, sizeof buf, "%u:1:%u:28:%u:1", id, ++msgid[i], m.epoch());
      m.handle_datagram(buf, static_cast<Peer>(i + 1), now);
      drain(m, nullptr);
    }
  }
}
#else
void elect(Master<>&, std::vector<std::uint32_t>&, Millis) {}
#endif

void PingFleet(benchmark::State& state, bool election) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const Millis t0 = 1000;
  MasterConfig cfg;
  cfg.election = election;
  Master<> m(cfg, t0);
  std::vector<std::uint32_t> msgid(n, 1);
  char buf[64];
  // Sync every agent: AGENT from temporary id 50000 + i at peer i + 1 (id 2 + i), ACK of MASTER.
  for (std::size_t i = 0; i < n; ++i) {
    std::snprintf(buf, sizeof buf, "%zu:0:1:1:A", 50000 + i);
    m.handle_datagram(buf, static_cast<Peer>(i + 1), t0);
    const auto id = static_cast<std::uint16_t>(2 + i);
    std::snprintf(buf, sizeof buf, "%u:1:%u:3:%u", id, ++msgid[i], m.registry().at(id).mid);
    m.handle_datagram(buf, static_cast<Peer>(i + 1), t0);
    std::snprintf(buf, sizeof buf, "%u:1:%u:5:ACTIVE", id, ++msgid[i]);
    m.handle_datagram(buf, static_cast<Peer>(i + 1), t0);
    drain(m, nullptr);
    if (election) elect(m, msgid, t0);
  }
  if (m.registry().size() != n) state.SkipWithError("not every agent registered");
  const Command behaviour = Command::assign("wait", {"seconds=3"});
  for (std::size_t k = 0; k < kPending; ++k)
    m.command(static_cast<std::uint16_t>(2 + k * n / kPending), behaviour, t0);
  drain(m, nullptr);

  Feed f{m, msgid, behaviour, t0};
  for (auto _ : state) f.step();
  const std::uint64_t k = f.k, sent = f.sent;
  const Millis now = f.now;
  if (m.registry().size() != n) state.SkipWithError("agents were dropped during the run");
  state.counters["agents"] = static_cast<double>(n);
  state.counters["sent_per_datagram"] = static_cast<double>(sent) / static_cast<double>(k);
  state.counters["core_seconds"] = static_cast<double>(now - t0) / 1000.0;
  state.counters["members"] = static_cast<double>(m.members().size());
}
void BM_MasterPing(benchmark::State& state) { PingFleet(state, false); }
BENCHMARK(BM_MasterPing)->Arg(100)->Arg(10000)->Unit(benchmark::kNanosecond);

#ifndef EV3_BENCH_BASELINE
// The same with the election on: the PC's membership (30 of the agents), its LEADER every 100 ms,
// the commands in EPOCH_CMD. Not in the baseline, whose core predates the election.
void BM_MasterPingElection(benchmark::State& state) { PingFleet(state, true); }
BENCHMARK(BM_MasterPingElection)->Arg(100)->Arg(10000)->Unit(benchmark::kNanosecond);
#endif

#ifndef EV3_BENCH_BASELINE
void BM_MasterReport(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const Millis t0 = 1000;
  Master<> m(MasterConfig{}, t0);
  std::vector<std::uint32_t> msgid(n, 1), seq(n, 0);
  char buf[160];
  for (std::size_t i = 0; i < n; ++i) {  // synced as in BM_MasterPing
    std::snprintf(buf, sizeof buf, "%zu:0:1:1:A", 50000 + i);
    m.handle_datagram(buf, static_cast<Peer>(i + 1), t0);
    const auto id = static_cast<std::uint16_t>(2 + i);
    std::snprintf(buf, sizeof buf, "%u:1:%u:3:%u", id, ++msgid[i], m.registry().at(id).mid);
    m.handle_datagram(buf, static_cast<Peer>(i + 1), t0);
    drain(m, nullptr);
  }
  std::uint64_t k = 0, sent = 0;
  Millis now = t0;
  for (auto _ : state) {
    const std::size_t i = k % n;
    const unsigned id = static_cast<unsigned>(2 + i);
    now = t0 + 1 + k * 1000 / kDatagramsPerSecond;
    ++msgid[i];
    std::snprintf(buf, sizeof buf, "%u:1:%u:40:%u:1:%u%%3A1%%3A%u%%3A18%%3Ain4%%3AUS-DIST-CM%%3A42", id, msgid[i],
                  ++seq[i], id, msgid[i]);
    m.handle_datagram(buf, static_cast<Peer>(i + 1), now);
    sent += drain(m, nullptr);
    benchmark::DoNotOptimize(m.next_deadline());
    ++k;
  }
  std::uint64_t recorded = 0;
  for (const auto& r : m.report_records()) recorded += r.second.reports;
  if (recorded != k) state.SkipWithError("not every report was recorded");
  state.counters["agents"] = static_cast<double>(n);
  state.counters["sent_per_datagram"] = static_cast<double>(sent) / static_cast<double>(k);
}
BENCHMARK(BM_MasterReport)->Arg(100)->Arg(10000)->Unit(benchmark::kNanosecond);
#endif

}  // namespace

BENCHMARK_MAIN();
