// Agent core and node unit tests: the transition table equals the spec's, the action names are the
// spec's, no heap use (the agent core; a node while it runs no Master core), window eviction.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <dirent.h>
#include <fstream>
#include <new>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <tuple>

#include "fixed_timers.hpp"
#include "ev3proto/agent.hpp"
#include "ev3proto/node.hpp"

#include "../count_new.hpp"  // g_news: every allocation of this test binary

namespace {
using namespace ev3proto;

// AllowedTransitions as written in spec/tla/AgentLogic.tla.
std::set<std::tuple<std::string, std::string, std::string>> spec_transitions() {
  std::ifstream in(EV3_AGENT_LOGIC_TLA);
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  const auto start = text.find("AllowedTransitions ==");
  EXPECT_NE(start, std::string::npos) << "AllowedTransitions not found in " << EV3_AGENT_LOGIC_TLA;
  const auto end = text.find('}', start);
  const std::string body = text.substr(start, end - start);
  std::set<std::tuple<std::string, std::string, std::string>> out;
  const std::regex tuple(R"re(<<\s*"(\w+)"\s*,\s*"(\w+)"\s*,\s*"(\w+)"\s*>>)re");
  for (std::sregex_iterator it(body.begin(), body.end(), tuple), e; it != e; ++it)
    out.emplace((*it)[1], (*it)[2], (*it)[3]);
  return out;
}

TEST(TransitionTable, EqualsSpecAllowedTransitions) {
  std::set<std::tuple<std::string, std::string, std::string>> cpp;
  for (const Transition& t : kTransitions)
    cpp.emplace(std::string(to_string(t.from)), std::string(to_string(t.to)), std::string(to_string(t.by)));
  const auto spec = spec_transitions();
  EXPECT_GE(spec.size(), 13u);
  EXPECT_EQ(cpp, spec);
}

TEST(TransitionTable, NextStateUsesTheTable) {
  EXPECT_EQ(next_state(State::WORKING, Action::HeartbeatLost).to, State::PAUSED);
  EXPECT_EQ(next_state(State::ACTIVE, Action::HeartbeatLost).to, State::PANIC);
  EXPECT_EQ(next_state(State::WORKING, Action::RecvStart).to, State::WORKING);  // a stay row
  EXPECT_FALSE(next_state(State::IDLE, Action::RecvStart));                     // no row: refused
  EXPECT_TRUE(next_state(State::WORKING, Action::RecvContinue, Wait::CONTINUE));
  EXPECT_FALSE(next_state(State::WORKING, Action::RecvContinue, Wait::RESTART));
  EXPECT_EQ(to_string(led_of(State::PAUSED)), "ORANGE");
}

TEST(TransitionTable, StaysKeepTheStateAndOFFHasNoRow) {
  for (const Transition& t : kStays) EXPECT_EQ(t.from, t.to) << to_string(t.by);
  for (std::size_t a = 0; a < kActionCount; ++a)
    for (Wait w : {Wait::NONE, Wait::CONTINUE, Wait::RESTART})
      EXPECT_FALSE(next_state(State::OFF, static_cast<Action>(a), w)) << to_string(static_cast<Action>(a));
}

// ---- the C++ action names are the spec's (docs/core.md: one handler per TLA+ action, same name)

std::string spec_dir() {
  const std::string f = EV3_AGENT_LOGIC_TLA;
  return f.substr(0, f.rfind('/'));
}

std::string read_file(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// Every operator a module of spec/tla defines (`Name(...) ==` or `Name ==` at a line's start).
std::set<std::string> spec_operators() {
  std::set<std::string> ops;
  DIR* d = opendir(spec_dir().c_str());
  if (d == nullptr) return ops;
  const std::regex def(R"re(^([A-Za-z][A-Za-z0-9_]*)\s*(\([^)]*\))?\s*==)re", std::regex::multiline);
  while (dirent* e = readdir(d)) {
    const std::string n = e->d_name;
    if (n.size() < 4 || n.substr(n.size() - 4) != ".tla") continue;
    const std::string text = read_file(spec_dir() + "/" + n);
    for (std::sregex_iterator it(text.begin(), text.end(), def), end; it != end; ++it) ops.insert((*it)[1]);
  }
  closedir(d);
  return ops;
}

/// The string elements of the TLA+ set `Name == {"A", "B", ...}` in @p module.
std::set<std::string> spec_name_set(const std::string& module, const std::string& name) {
  const std::string text = read_file(spec_dir() + "/" + module);
  const auto at = text.find(name + " ==");
  std::set<std::string> out;
  if (at == std::string::npos) return out;
  const std::string body = text.substr(at, text.find('}', at) - at);
  const std::regex str(R"re("(\w+)")re");
  for (std::sregex_iterator it(body.begin(), body.end(), str), e; it != e; ++it) out.insert((*it)[1]);
  return out;
}

// The C++ actions the spec abstracts (docs/core.md "Relay and election"): the master reads the relay
// table (RELAY_ROUTE). The handover of a stepping-down master is System.tla's MasterHandover.
// The agent's EVENT(LEAVING) as its program exits is no protocol step (Agent::leaving).
const std::set<std::string> kCppOnly = {"MasterRoute", "Leave"};

TEST(ActionNames, EveryCppActionIsASpecAction) {
  const std::set<std::string> ops = spec_operators();
  ASSERT_GT(ops.size(), 100u) << "no TLA+ modules read in " << spec_dir();
  for (std::size_t i = 0; i < kActionCount; ++i) {
    const std::string a(to_string(static_cast<Action>(i)));
    if (kCppOnly.count(a) != 0) {
      EXPECT_EQ(ops.count(a), 0u) << a << " is a spec action now: drop it from kCppOnly";
      continue;
    }
    EXPECT_EQ(ops.count(a), 1u) << "Action::" << a << " is defined by no module of spec/tla";
  }
}

TEST(ActionNames, EverySpecActionOfANodeIsACppAction) {
  std::set<std::string> cpp;
  for (std::size_t i = 0; i < kActionCount; ++i) cpp.insert(std::string(to_string(static_cast<Action>(i))));
  std::set<std::string> spec = spec_name_set("AgentLogic.tla", "RecvNames");
  for (const auto& n : spec_name_set("AgentLogic.tla", "InternalNames")) spec.insert(n);
  for (const auto& n : spec_name_set("MasterLogic.tla", "MasterNames")) spec.insert(n);
  ASSERT_GE(spec.size(), 28u);
  // Election.tla's Next: the actions its nodes take (the environment's and the two the cores name
  // otherwise are listed: Timeout is the agent's HeartbeatLost, SendCommand the master's
  // MasterCommand, docs/core.md).
  const std::string text = read_file(spec_dir() + "/Election.tla");
  const auto at = text.find("\nNext ==");
  ASSERT_NE(at, std::string::npos);
  const std::string next = text.substr(at, text.find("\nSpec ==", at) - at);
  const std::regex call(R"re(([A-Z][A-Za-z]*)\()re");
  // AddMember / DropMember: the PC's registry changing (RecvAgent; MasterTick's drop, which calls the
  // master core's DropMember: no record of its own, the registry's drop is MasterTick's).
  const std::set<std::string> environment = {"Crash", "Restart", "Cut", "Heal", "Lose", "Timeout", "SendCommand",
                                             "AddMember", "DropMember"};
  std::size_t election = 0;
  for (std::sregex_iterator it(next.begin(), next.end(), call), e; it != e; ++it) {
    if (environment.count((*it)[1]) != 0) continue;
    spec.insert((*it)[1]);
    ++election;
  }
  EXPECT_GE(election, 14u);
  EXPECT_EQ(spec.count("ShareMembers") + spec.count("LearnMembers"), 2u);  // the membership rules
  for (const auto& n : spec) EXPECT_EQ(cpp.count(n), 1u) << "spec action " << n << " has no Action";
}

constexpr BehaviourSpec kBehs[] = {{"explore", 1u}, {"wander", 0u}};

AgentConfig config() {
  AgentConfig c;
  c.timers = ev3test::fixed_timers();
  c.caps = Capabilities{"A", kBehs, 2, 1u};
  c.temp_id = 50001;
  return c;
}

template <typename A>
void drain(A& a) {
  Transmit t;
  while (a.poll_transmit(t)) {
  }
  AgentEvent e;
  while (a.poll_event(e)) {
  }
}

TEST(AgentNoHeap, WholeLifecycleAllocatesNothing) {
  alignas(Agent<>) static unsigned char storage[sizeof(Agent<>)];
  const long before = g_news.load();
  Agent<>* a = new (storage) Agent<>(config(), 0);  // placement: no allocation
  for (int round = 0; round < 3; ++round) {
    const Millis t0 = static_cast<Millis>(round) * 100000u;
    a->advance(t0 + 1000);
    const char* master = round == 0 ? "1:5:1:2:50001" : "1:5:100:2:5";
    a->handle_datagram(round == 0 ? master : master, 1, t0 + 1001);
    char buf[64];
    std::snprintf(buf, sizeof buf, "1:5:%d:7:explore:speed=3", 2 + round * 10);
    a->handle_datagram(buf, 1, t0 + 1002);
    std::snprintf(buf, sizeof buf, "1:5:%d:8", 3 + round * 10);
    a->handle_datagram(buf, 1, t0 + 1003);
    a->handle_datagram(buf, 1, t0 + 1004);  // duplicate
    a->action_ok(t0 + 1005);
    const std::string_view v[1] = {"42"};
    a->sensor_report("in1", "US-DIST-CM", v, 1, t0 + 1006);
    a->action_interrupted(Warning::OBSTACLE_DETECTED, t0 + 1007);
    a->handle_datagram("garbage", 1, t0 + 1008);
    a->robot_event(RobotEventKind::OBSTACLE_DETECTED, "in1", t0 + 1008);
    a->device_unplugged(1, "outB", t0 + 1009);
    a->device_plugged(1, "outB", t0 + 1010);
    a->advance(t0 + 20000);  // master lost: PANIC
    drain(*a);
  }
  a->battery_low(400000);
  drain(*a);
  EXPECT_EQ(g_news.load(), before) << "the agent core allocated";
  EXPECT_EQ(a->state(), State::OFF);
  a->~Agent<>();
}

TEST(AgentNoHeap, RelayAndElectionAllocateNothing) {
  alignas(Agent<>) static unsigned char storage[sizeof(Agent<>)];
  AgentConfig c = config();
  c.election.enabled = true;
  c.election.score = 5;
  const long before = g_news.load();
  Agent<>* a = new (storage) Agent<>(c, 0);
  a->handle_datagram("1:7:1:2:50001", 1, 10);            // synced as 7
  a->handle_datagram("1:0:2:29:1:1:7:8:9", 1, 20);       // LEADER: members
  a->handle_datagram("9:0:5:21:1", 9, 30);                // RELAY_REQ -> OfferRelay
  a->handle_datagram("9:7:6:23:1:1", 9, 40);              // HandleAccept
  a->handle_datagram("1:7:3:25:9:1%3A9%3A4%3A6%3A5", 1, 50);  // Forward to 9
  a->handle_datagram("9:7:7:25:1:9%3A1%3A7%3A5%3AACTIVE", 9, 60);  // Forward to the master
  drain(*a);
  a->advance(10000);                                      // PANIC: RELAY_DROP, RELAY_REQ, stand
  a->handle_datagram("8:7:3:28:2:7", 8, 10001);           // vote -> BecomeMaster (epoch 2)
  a->handle_datagram("1:0:9:27:3:0:0", 1, 10002);         // the PC stands: step down, vote
  a->handle_datagram("1:0:10:29:3:1:7:8:9", 1, 10003);    // follow the PC in epoch 3
  a->handle_datagram("1:7:11:31:3:1%3A7%3A11%3A7%3Aexplore", 1, 10004);  // ApplyCommand
  a->handle_datagram("1:7:12:31:2:1%3A7%3A12%3A8", 1, 10005);            // older: EPOCH_STALE
  a->handle_datagram("1:7:13:8", 1, 10006);               // bare: fenced
  a->handle_datagram("2:7:1:30:9", 2, 10007);             // HandleStale
  a->advance(40000);
  drain(*a);
  EXPECT_EQ(g_news.load(), before) << "the agent core allocated";
  EXPECT_GE(a->election().epoch, 9u);  // then it stood alone (no majority) in later epochs
  a->~Agent<>();
}

TEST(AgentNoHeap, CounterSeesAllocations) {  // the counter itself works
  const long before = g_news.load();
  void* p = ::operator new(16);  // a direct call: cannot be elided like a new-expression
  ::operator delete(p);
  EXPECT_EQ(g_news.load(), before + 1);
}

/// A node that never wins an epoch allocates nothing: its Master core, the only part that
/// allocates, never runs. Election on: relay requests, a relay, a vote, a newer epoch.
TEST(NodeNoHeap, NoMasterCoreNoAllocation) {
  using N = Node<>;
  alignas(N) static unsigned char storage[sizeof(N)];
  N::Config c;
  c.agent = config();
  c.agent.election.enabled = true;
  c.agent.election.score = 50;
  const long before = g_news.load();
  N* n = new (storage) N(c, 0);  // placement: no allocation (an empty std::function allocates nothing)
  auto drain_node = [n] {
    NodeEvent e;  // events first: a durable change holds the datagrams until it is handed out
    while (n->poll_event(e)) {
    }
    NodeTransmit t;
    while (n->poll_transmit(t)) {
    }
  };
  n->handle_datagram("1:7:1:2:50001", 1, 10);
  n->handle_datagram("1:0:2:29:1:1:7:8:9", 1, 20);
  n->handle_datagram("9:0:5:21:1", 9, 30);
  n->handle_datagram("9:7:6:23:1:1", 9, 40);
  n->handle_datagram("1:7:3:25:9:1%3A9%3A4%3A6%3A5", 1, 50);
  n->handle_datagram("1:7:4:7:explore", 1, 60);
  n->handle_datagram("1:7:5:8", 1, 70);
  n->action_ok(80);
  n->handle_datagram("garbage", 1, 90);
  drain_node();
  n->advance(10000);
  n->handle_datagram("8:0:3:27:2:5:0", 8, 10001);  // a weaker candidate: vote, epoch 2
  n->advance(20000);
  drain_node();
  EXPECT_EQ(g_news.load(), before) << "the node allocated";
  EXPECT_EQ(n->master(), nullptr);
  EXPECT_EQ(n->agent().election().epoch, 2u);
  n->~N();
}

TEST(AgentWindow, EvictedCommandIsActedOnAgain) {
  Agent<NoTrace, 2> a(config(), 0);
  a.handle_datagram("1:5:1:2:50001", 1, 1);
  EXPECT_EQ(a.handle_datagram("1:5:2:7:wander", 1, 2).action, Action::RecvBehaviour);
  EXPECT_EQ(a.handle_datagram("1:5:3:8", 1, 3).action, Action::RecvStart);  // window now {2, 3}: MASTER evicted
  EXPECT_EQ(a.handle_datagram("1:5:2:7:wander", 1, 4).action, Action::RecvDuplicate);
  EXPECT_EQ(a.handle_datagram("1:5:1:2:50001", 1, 5).action, Action::Ignore);  // evicted, not masterless
  EXPECT_EQ(a.window().size(), 2u);
}

TEST(AgentQueues, OverflowDropsOldestAndCounts) {
  Agent<NoTrace, 50, 2, 64, 2> a(config(), 0);
  a.advance(1000);
  a.advance(2000);
  a.advance(3000);  // three AGENT broadcasts into two slots
  EXPECT_EQ(a.overflowed(), 1u);
  Transmit t;
  ASSERT_TRUE(a.poll_transmit(t));
  EXPECT_EQ(t.bytes, "50001:0:2:1:A");
  ASSERT_TRUE(a.poll_transmit(t));
  EXPECT_FALSE(a.poll_transmit(t));
  // A sensor report that cannot fit the slot is refused and drops nothing.
  a.handle_datagram("1:5:1:2:50001", 1, 3001);
  a.handle_datagram("1:5:2:7:wander", 1, 3002);
  a.handle_datagram("1:5:3:8", 1, 3003);
  drain(a);
  const std::string big(100, 'x');
  const std::string_view v[1] = {big};
  EXPECT_FALSE(a.sensor_report("in1", "m", v, 1, 3004));
  EXPECT_FALSE(a.poll_transmit(t));
}

TEST(AgentAnnouncement, AgentCarriesTheModelThenItsNamedDevicesPluggedOrNot) {
  constexpr std::string_view kNames[] = {"left motor", "right motor", "colour sensor"};
  AgentConfig c = config();
  c.caps.devices = 1u | 4u | 8u;  // bit 3 has no name: left out
  c.caps.device_names = kNames;
  c.caps.device_name_count = 3;
  Agent<> a(c, 0);
  a.device_unplugged(4u, "in3", 10);  // missing: still announced, the model has it
  a.advance(1000);
  Transmit t;
  ASSERT_TRUE(a.poll_transmit(t));
  EXPECT_EQ(t.bytes, "50001:0:1:1:A:left motor:colour sensor");
  Agent<> plain(config(), 0);  // devices without names: the model alone
  plain.advance(1000);
  ASSERT_TRUE(plain.poll_transmit(t));
  EXPECT_EQ(t.bytes, "50001:0:1:1:A");
}

TEST(AgentBehaviour, ArgumentsBeyondCapacityAreRefused) {
  Agent<NoTrace, 50, 8, 512, 16, 4> a(config(), 0);
  a.handle_datagram("1:5:1:2:50001", 1, 1);
  drain(a);
  EXPECT_EQ(a.handle_datagram("1:5:2:7:wander:speed=3", 1, 2).action, Action::RecvBehaviour);
  Transmit t;
  ASSERT_TRUE(a.poll_transmit(t));
  EXPECT_EQ(t.bytes, "5:1:2:4:2:unknown behaviour");
  EXPECT_TRUE(a.behaviour().name.empty());
}

TEST(AgentTime, PastTimeChangesNothingAndDeadlineIsExact) {
  Agent<> a(config(), 500);
  EXPECT_EQ(a.next_deadline(), 1500u);
  a.advance(100);
  EXPECT_EQ(a.now(), 500u);
  a.advance(10500);  // sync 10000 after start: PANIC at 10500
  EXPECT_EQ(a.state(), State::PANIC);
  EXPECT_EQ(a.next_deadline(), 11500u);
  a.battery_low(10600);
  EXPECT_EQ(a.next_deadline(), Agent<>::kNever);
  a.advance(20000);
  EXPECT_EQ(a.now(), 20000u);
  EXPECT_EQ(a.handle_datagram("1:50001:1:2:50001", 1, 20001).action, Action::Ignore);  // OFF: no step
}

TEST(Timers, DefaultsAndSpecMapping) {
  const Timers t;
  EXPECT_EQ(t[Timer::sync], 10000u);
  EXPECT_EQ(t[Timer::heartbeat], 100u);
  EXPECT_EQ(t[Timer::loss], 800u);
  EXPECT_EQ(t[Timer::paused], 1000u);
  EXPECT_TRUE(t.valid());
  const Timers m = Timers::from_ticks(2, 1, 2, 3, 3);
  EXPECT_EQ(m[Timer::resend], 1u);
  EXPECT_EQ(m[Timer::drop], 3u);
  EXPECT_TRUE(m.valid());
  Timers bad;
  bad.set(Timer::paused, 0);
  EXPECT_EQ(bad[Timer::paused], 1u);
  EXPECT_FALSE(bad.valid());
  EXPECT_EQ(to_string(Timer::resend), "resend");
}

TEST(Timers, AllButSyncAreMultiplesOfTheHeartbeat) {
  const Timers t = Timers::for_heartbeat(200);
  EXPECT_EQ(t[Timer::heartbeat], 200u);
  EXPECT_EQ(t[Timer::loss], 1600u);
  EXPECT_EQ(t[Timer::paused], 2000u);
  EXPECT_EQ(t[Timer::backoff], 400u);
  EXPECT_EQ(t[Timer::backoff_step], 200u);
  EXPECT_EQ(t[Timer::backoff_jitter], 100u);
  EXPECT_EQ(t[Timer::sync], Timers{}[Timer::sync]);
  EXPECT_EQ(Timers::for_heartbeat(1)[Timer::backoff_jitter], 1u);  // never 0
  EXPECT_TRUE(Timers::for_heartbeat(1).valid());
}

// The back-off before standing: backoff (+ backoff_step per weaker peer heard asking: none here),
// and with a seed a random part in [0, backoff_jitter), drawn anew at each PANIC.
TEST(AgentElection, BackoffHasARandomPartOnlyWithASeed) {
  auto stand_after = [](std::uint32_t seed, int panics) {
    AgentConfig c = config();
    c.timers = Timers::for_heartbeat(100);
    c.election.enabled = true;
    c.election.score = 10;
    c.election.seed = seed;
    Agent<> a(c, 0);
    a.handle_datagram("1:7:1:2:50001", 1, 10);       // synced as 7
    a.handle_datagram("1:0:2:29:1:1:7:8:9", 1, 20);  // LEADER: members 7, 8, 9
    std::vector<Millis> out;
    Millis now = 20;
    for (int i = 0; i < panics; ++i) {
      const Millis panic_at = now + 800;  // the master silent for 800 ms (loss): PANIC
      now += 1000;
      a.advance(now);
      out.push_back(a.election().stand_at - panic_at);
      a.handle_datagram("1:0:" + std::to_string(3 + i) + ":29:1:1:7:8:9", 1, now);  // the master back
    }
    return out;
  };
  const std::vector<Millis> fixed = stand_after(0, 3);
  const Millis base = 200;
  EXPECT_EQ(fixed, (std::vector<Millis>{base, base, base}));
  const std::vector<Millis> a = stand_after(12345, 8), b = stand_after(777, 8);
  EXPECT_EQ(a, stand_after(12345, 8));  // the seed decides
  EXPECT_NE(a, b);
  bool varied = false;
  for (Millis v : a) {
    EXPECT_GE(v, base);
    EXPECT_LT(v, base + 50);
    varied = varied || v != a[0];
  }
  EXPECT_TRUE(varied);
}

TEST(CheckReason, KeepsAShortReasonAndCutsALongOneAtACharacterWithDots) {
  CheckReason r;
  r.set("line 4 col 12: unknown action 'trun'");
  EXPECT_EQ(r.view(), "line 4 col 12: unknown action 'trun'");
  const std::string exact(CheckReason::kMax, 'x');
  r.set(exact);
  EXPECT_EQ(r.view(), exact);
  // 116 ASCII bytes, then "é" (2 bytes) across the cut at 117: the whole character goes.
  const std::string text = std::string(116, 'a') + "\xC3\xA9" + std::string(20, 'b');
  r.set(text);
  EXPECT_EQ(r.view(), std::string(116, 'a') + "...");
  r.set("");
  EXPECT_EQ(r.view(), "");
}

TEST(Names, ActionAndEnumSpellings) {
  EXPECT_EQ(to_string(Action::RecvDuplicate), "RecvDuplicate");
  EXPECT_EQ(to_string(Action::MasterTick), "MasterTick");
  EXPECT_EQ(to_string(Action::Tick), "Tick");
  EXPECT_EQ(to_string(static_cast<Action>(200)), "");
  EXPECT_EQ(to_string(Refusal::missing_device), "missing device");
  EXPECT_EQ(to_string(Wait::RESTART), "RESTART");
  EXPECT_EQ(to_string(Dest::peer), "peer");
  EXPECT_EQ(to_string(ControlKind::resume), "resume");
  EXPECT_EQ(to_string(Warning::PROXIMITY_ALERT), "PROXIMITY_ALERT");
  EXPECT_EQ(wire_state(State::OFF), AgentState::PANIC);
  EXPECT_FALSE(is_assigned_id(50000));
}

}  // namespace
