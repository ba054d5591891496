// Whole-fleet scenarios over a lossy, duplicating, reordering network, seeds swept, invariants
// checked after every step (tests/cpp/sim/fleet_sim.hpp).
#include <gtest/gtest.h>

#include <set>
#include <string>

#include "../core/fixed_timers.hpp"
#include "fleet_sim.hpp"

namespace {

using namespace ev3sim;

/// Fleet.tla's safety invariants, checked on the real cores after every step.
struct Invariants {
  std::string failure;
  void operator()(Fleet& f) {
    if (!failure.empty()) return;
    std::set<std::uint16_t> ids;
    for (std::size_t i = 0; i < f.size(); ++i) {
      const Agent<>& a = f.agent(i);
      const std::string who = "agent " + std::to_string(i) + " at " + std::to_string(f.now()) + ": ";
      if (a.led() != led_of(a.state())) failure = who + "LED does not match the state";          // LedInv
      if (a.motors() && a.state() != State::WORKING) failure = who + "motion outside WORKING";  // BehaviourOnlyInWorking
      if (a.state() == State::WORKING && f.now() - a.last_heard() > f.timers()[Timer::loss])
        failure = who + "WORKING unsupervised";                                                // NoUnsupervisedMotion
      if (is_synced(a.state()) && !ids.insert(a.id()).second)
        failure = who + "id " + std::to_string(a.id()) + " held twice";                        // UniqueIds
    }
  }
};

bool all_in(Fleet& f, State s) {
  for (std::size_t i = 0; i < f.size(); ++i)
    if (f.agent(i).state() != s) return false;
  return true;
}

std::size_t count_ops(const Fleet& f, OperatorEvent::Kind k, MsgType t) {
  std::size_t n = 0;
  for (const auto& e : f.ops) n += e.kind == k && e.command == t ? 1u : 0u;
  return n;
}

constexpr std::size_t kAgents = 4;

/// The whole story for one seed: sync under loss, behaviour started on all, master crash (all
/// PAUSED then PANIC, never WORKING past the loss timeout), restart, everyone resyncs.
void scenario(std::uint64_t seed, double loss) {
  SCOPED_TRACE("seed " + std::to_string(seed));
  NetConfig net;
  net.loss = loss;
  net.dup = 0.1;
  Fleet f(kAgents, seed, net);
  Invariants inv;
  auto check = [&](Fleet& x) { inv(x); };

  // 1. Everyone syncs with a unique id.
  f.run_until(30000, check);
  ASSERT_TRUE(inv.failure.empty()) << inv.failure;
  ASSERT_TRUE(all_in(f, State::ACTIVE)) << "not all ACTIVE after 30 s";
  std::set<std::uint16_t> ids;
  for (std::size_t i = 0; i < f.size(); ++i) ids.insert(f.agent(i).id());
  ASSERT_EQ(ids.size(), kAgents);
  for (auto id : ids) ASSERT_TRUE(is_assigned_id(id));

  // 2. A behaviour assigned and started on all.
  f.command(0, Command::assign("explore", {"speed=3"}));
  f.command(0, Command::simple(MsgType::START));
  f.run_until(f.now() + 10000, check);
  ASSERT_TRUE(inv.failure.empty()) << inv.failure;
  // Exactly one each per agent: a PING(ACTIVE) that arrives after the START's ACK (reordered or a
  // late copy) is stale (msgid below the ACK's) and does not reconcile (MasterLogic MasterPing).
  EXPECT_EQ(count_ops(f, OperatorEvent::Kind::acked, MsgType::BEHAVIOUR), kAgents);
  EXPECT_EQ(count_ops(f, OperatorEvent::Kind::acked, MsgType::START), kAgents);
  for (std::size_t i = 0; i < f.size(); ++i) {
    const State s = f.agent(i).state();
    // A spurious heartbeat loss (every copy of PING or PONG lost 3 times) may have paused one
    // (reconcile resumes it on its next PING).
    EXPECT_TRUE(s == State::WORKING || s == State::PAUSED) << "agent " << i << " " << to_string(s);
    EXPECT_EQ(f.agent(i).behaviour().name, "explore");
  }

  // 3. The master crashes: no agent stays WORKING past the loss timeout, all end in PANIC.
  f.crash_master();
  const Millis crash = f.now();
  f.run_until(crash + f.timers()[Timer::loss] + 1, [&](Fleet& x) {
    inv(x);
  });
  for (std::size_t i = 0; i < f.size(); ++i) EXPECT_NE(f.agent(i).state(), State::WORKING);
  f.run_until(crash + f.timers()[Timer::paused] + 1, check);
  ASSERT_TRUE(inv.failure.empty()) << inv.failure;
  EXPECT_TRUE(all_in(f, State::PANIC));

  // 4. The master restarts with an empty registry: all resync, each with its old id.
  std::vector<std::uint16_t> old;
  for (std::size_t i = 0; i < f.size(); ++i) old.push_back(f.agent(i).id());
  f.run_until(f.now() + 5000, check);
  f.restart_master();
  f.run_until(f.now() + 30000, check);
  ASSERT_TRUE(inv.failure.empty()) << inv.failure;
  EXPECT_TRUE(all_in(f, State::ACTIVE));
  for (std::size_t i = 0; i < f.size(); ++i) EXPECT_EQ(f.agent(i).id(), old[i]);
}

std::size_t count_after(const Fleet& f, std::size_t from, OperatorEvent::Kind k, MsgType t) {
  std::size_t n = 0;
  for (std::size_t i = from; i < f.ops.size(); ++i) n += f.ops[i].kind == k && f.ops[i].command == t ? 1u : 0u;
  return n;
}

/// Reconcile (MasterLogic MasterPing): agents paused by a lost heartbeat are resumed, agents that
/// went to PANIC and resynced (ACTIVE, behaviour unloaded) get BEHAVIOUR + START again; an operator
/// PAUSE is kept (no RESUME from the master) through a partition, and so is an operator STOP.
void reconcile_scenario(std::uint64_t seed, double loss) {
  SCOPED_TRACE("seed " + std::to_string(seed));
  NetConfig net;
  net.loss = loss;
  net.dup = 0.1;
  // The transcripts' timers (1 s heartbeat, master timeout 3 s, paused 6 s): a partition between
  // the two timeouts is PAUSED for every agent whatever its last PONG's age (with the defaults'
  // 800 ms and 1 s the window is two heartbeats wide).
  Fleet f(kAgents, seed, net, ev3test::fixed_timers());
  Invariants inv;
  auto check = [&](Fleet& x) { inv(x); };
  auto partition = [&](Millis ms) {
    f.set_loss(1.0);
    f.run_until(f.now() + ms, check);
    f.set_loss(loss);
  };
  f.run_until(30000, check);
  ASSERT_TRUE(all_in(f, State::ACTIVE));
  f.command(0, Command::assign("explore", {"speed=3"}));
  f.command(0, Command::simple(MsgType::START));
  f.run_until(f.now() + 10000, check);
  ASSERT_TRUE(inv.failure.empty()) << inv.failure;

  // 1. A partition longer than the loss timeout: every agent PAUSED; healed: resumed.
  partition(f.timers()[Timer::loss] + 500);
  EXPECT_TRUE(all_in(f, State::PAUSED));
  std::size_t mark = f.ops.size();
  f.run_until(f.now() + 10000, check);
  ASSERT_TRUE(inv.failure.empty()) << inv.failure;
  EXPECT_TRUE(all_in(f, State::WORKING));
  EXPECT_GE(count_after(f, mark, OperatorEvent::Kind::acked, MsgType::RESUME), 1u);

  // 2. Longer than the paused timeout (the master still holds them): PANIC, resync, and the
  //    behaviour (with its arguments) is assigned and started again.
  partition(f.timers()[Timer::paused] + 1000);
  EXPECT_TRUE(all_in(f, State::PANIC));
  f.run_until(f.now() + 15000, check);
  ASSERT_TRUE(inv.failure.empty()) << inv.failure;
  EXPECT_TRUE(all_in(f, State::WORKING));
  for (std::size_t i = 0; i < f.size(); ++i) {
    EXPECT_EQ(f.agent(i).behaviour().name, "explore");
  }

  // 3. The operator pauses everyone: nothing undoes it, not even a partition.
  f.command(0, Command::simple(MsgType::PAUSE));
  f.run_until(f.now() + 10000, check);
  mark = f.ops.size();
  partition(f.timers()[Timer::loss] + 500);
  f.run_until(f.now() + 10000, check);
  ASSERT_TRUE(inv.failure.empty()) << inv.failure;
  EXPECT_TRUE(all_in(f, State::PAUSED));
  EXPECT_EQ(count_after(f, mark, OperatorEvent::Kind::acked, MsgType::RESUME), 0u);
  EXPECT_EQ(count_after(f, mark, OperatorEvent::Kind::acked, MsgType::START), 0u);

  // 4. The operator stops everyone: they stay ACTIVE (no START from the master).
  f.command(0, Command::simple(MsgType::STOP));
  f.run_until(f.now() + 10000, check);
  mark = f.ops.size();
  f.run_until(f.now() + 10000, check);
  ASSERT_TRUE(inv.failure.empty()) << inv.failure;
  EXPECT_TRUE(all_in(f, State::ACTIVE));
  EXPECT_EQ(count_after(f, mark, OperatorEvent::Kind::acked, MsgType::START), 0u);
}

TEST(FleetSim, OneSeedPerfectNetwork) { scenario(1, 0.0); }

TEST(FleetSim, ReconcilePerfectNetwork) { reconcile_scenario(1, 0.0); }

TEST(FleetSim, ReconcileSeedsSweptUnder10PercentLoss) {
  for (std::uint64_t seed = 1; seed <= 100; ++seed) {
    reconcile_scenario(seed, 0.10);
    if (::testing::Test::HasFailure()) break;
  }
}

TEST(FleetSim, SeedsSweptUnder30PercentLoss) {
  for (std::uint64_t seed = 1; seed <= 200; ++seed) {
    scenario(seed, 0.30);
    if (::testing::Test::HasFailure()) break;
  }
}

TEST(FleetSim, TwoAgentsSyncWithinOneHeartbeatOnAPerfectNetwork) {
  Fleet f(2, 7, NetConfig{});
  Invariants inv;
  f.run_until(1100, [&](Fleet& x) { inv(x); });
  EXPECT_TRUE(inv.failure.empty());
  EXPECT_TRUE(all_in(f, State::ACTIVE));
  EXPECT_NE(f.agent(0).id(), f.agent(1).id());
}

TEST(FleetSim, IsDeterministic) {
  auto run = [](std::uint64_t seed) {
    NetConfig net;
    net.loss = 0.3;
    net.dup = 0.2;
    Fleet f(3, seed, net);
    f.run_until(20000, nullptr);
    std::string s;
    for (std::size_t i = 0; i < f.size(); ++i)
      s += std::to_string(f.agent(i).id()) + std::string(to_string(f.agent(i).state())) + ",";
    return s + std::to_string(f.ops.size());
  };
  EXPECT_EQ(run(42), run(42));
}

}  // namespace
