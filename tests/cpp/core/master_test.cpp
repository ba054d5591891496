// The master core's deadlines (DeadlineList) against plain walks: after every call the earliest
// deadline the core reports equals the one a walk of its registry finds, over long random runs.
#include <gtest/gtest.h>

#include <cstdint>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "ev3proto/deadline_list.hpp"
#include "ev3proto/master.hpp"

namespace {

using namespace ev3proto;

TEST(DeadlineList, EqualsAMapOfDeadlinesOverRandomOperations) {
  std::mt19937 rng(7);
  const Millis period = 40;
  DeadlineList<std::uint16_t> l(period);
  std::map<std::uint16_t, Millis> model;  // key -> deadline
  Millis now = 0;
  auto earliest = [&] {
    Millis e = DeadlineList<std::uint16_t>::kNever;
    for (const auto& kv : model) e = std::min(e, kv.second);
    return e;
  };
  for (int step = 0; step < 200000; ++step) {
    const std::uint16_t k = static_cast<std::uint16_t>(rng() % 64);
    switch (rng() % 5) {
      case 0:
      case 1: {  // refreshed now (the master's case), or earlier now and then (placed by a scan)
        const Millis at = rng() % 8 == 0 && now > 30 ? now - rng() % 30 : now;
        l.refresh(k, at);
        model[k] = at + period;
        break;
      }
      case 2:
        l.remove(k);
        model.erase(k);
        break;
      case 3:
        now += rng() % 5;
        break;
      default: {
        now += rng() % 20;
        for (std::uint16_t got = 0; l.pop_due(now, got);) {
          ASSERT_EQ(model.count(got), 1u) << "step " << step;
          ASSERT_EQ(model[got], earliest()) << "pop_due takes the earliest, step " << step;
          ASSERT_LE(model[got], now);
          model.erase(got);
        }
        ASSERT_GT(earliest(), now) << "a due key was left, step " << step;
        break;
      }
    }
    ASSERT_EQ(l.next(), earliest()) << "step " << step;
    ASSERT_EQ(l.size(), model.size());
    ASSERT_EQ(l.deadline(k), model.count(k) ? model[k] : DeadlineList<std::uint16_t>::kNever);
  }
}

/// The earliest deadline by walking the registry: the reference next_deadline() must equal.
Millis walked_deadline(const Master<>& m, const Timers& t) {
  Millis d = Master<>::kNever;
  for (const auto& kv : m.registry()) {
    const RegistryEntry& e = kv.second;
    d = std::min(d, e.heard + t[Timer::drop]);
    if (e.pending) d = std::min(d, e.sent_at + t[Timer::resend]);
  }
  return d;
}

/// Random traffic of up to 40 agents (syncs, PANICs, answers right and wrong, PINGs in every state,
/// reports, copies, operator commands, time moving by small and large steps).
void random_run(std::uint32_t seed, Millis resend, Millis drop) {
  std::mt19937 rng(seed);
  MasterConfig c;
  c.timers.set(Timer::resend, resend).set(Timer::drop, drop);
  c.max_resends = 3;
  Master<> m(c, 1000);
  Millis now = 1000;
  std::map<std::uint16_t, std::uint32_t> msgid;  // per sender
  const char* states[] = {"ACTIVE", "WORKING", "PAUSED", "IDLE", "PANIC"};
  const MsgType cmds[] = {MsgType::START, MsgType::STOP, MsgType::PAUSE, MsgType::RESUME, MsgType::STANDBY};
  auto pick = [&]() -> const RegistryEntry* {
    if (m.registry().empty()) return nullptr;
    auto it = m.registry().begin();
    std::advance(it, static_cast<long>(rng() % m.registry().size()));
    return &it->second;
  };
  std::map<OperatorEvent::Kind, int> seen;
  std::size_t most = 0;
  for (int step = 0; step < 20000; ++step) {
    const auto peer = static_cast<Peer>(1 + rng() % 45);
    std::string d;
    switch (rng() % 9) {
      case 0: {  // AGENT from a temporary id (a copy now and then: same msgid)
        const auto t = static_cast<std::uint16_t>(50000 + rng() % 40);
        const std::uint32_t id = rng() % 4 == 0 ? msgid[t] : ++msgid[t];
        d = std::to_string(t) + ":0:" + std::to_string(id) + ":1:A";
        break;
      }
      case 1:
        if (const RegistryEntry* e = pick()) {  // PANIC from an assigned id
          d = std::to_string(e->id) + ":0:" + std::to_string(++msgid[e->id]) + ":19";
        }
        break;
      case 2:
      case 3:
        if (const RegistryEntry* e = pick()) {  // ACK or NOT of the pending msgid, or of a wrong one
          const std::uint32_t ref = rng() % 5 == 0 ? e->mid + 1 : e->mid;
          d = std::to_string(e->id) + ":1:" + std::to_string(++msgid[e->id]) +
              (rng() % 4 == 0 ? ":4:" + std::to_string(ref) + ":wrong state" : ":3:" + std::to_string(ref));
        }
        break;
      case 4:
      case 5:
        if (const RegistryEntry* e = pick()) {  // PING, sometimes stale
          const std::uint32_t id = rng() % 5 == 0 ? msgid[e->id] : ++msgid[e->id];
          d = std::to_string(e->id) + ":1:" + std::to_string(id) + ":5:" + states[rng() % 5];
        }
        break;
      case 6: {
        const RegistryEntry* e = pick();
        const std::uint16_t id = e == nullptr || rng() % 6 == 0 ? 0 : e->id;
        m.command(id, Command::simple(cmds[rng() % 5]), now);
        break;
      }
      case 7:
        now += rng() % (resend + 2);
        m.advance(now);
        break;
      default:
        now += rng() % (drop / 3 + 1);
        m.advance(now);
        break;
    }
    if (!d.empty()) m.handle_datagram(d, peer, now);
    MasterTransmit t;
    while (m.poll_transmit(t)) {
    }
    OperatorEvent ev;
    while (m.poll_event(ev)) ++seen[ev.kind];
    most = std::max(most, m.registry().size());
    ASSERT_EQ(m.next_deadline(), walked_deadline(m, c.timers)) << "seed " << seed << " step " << step << " " << d;
    ASSERT_GT(m.next_deadline(), m.now()) << "a due deadline was left behind, step " << step;
  }
  // The run went through what it is meant to: registrations, answers, failures, drops.
  EXPECT_GT(most, 10u);
  for (auto k : {OperatorEvent::Kind::registered, OperatorEvent::Kind::acked, OperatorEvent::Kind::refused,
                 OperatorEvent::Kind::timed_out, OperatorEvent::Kind::dropped})
    EXPECT_GT(seen[k], 10) << "seed " << seed << ": too few " << to_string(k);
}

TEST(MasterDeadlines, NextDeadlineEqualsAWalkOfTheRegistry) {
  random_run(1, 500, 10000);
  random_run(2, 1, 10);
  random_run(3, 7, 40);
  random_run(4, 100, 1000);
}

}  // namespace

namespace {

std::vector<std::string> sent(Master<>& m) {
  std::vector<std::string> out;
  MasterTransmit t;
  while (m.poll_transmit(t)) out.push_back(t.bytes);
  return out;
}

void expect_receipt(const MasterReceipt& r, Action a, MasterIgnored why, Reason reason = Reason::ok) {
  EXPECT_EQ(to_string(r.action), to_string(a));
  EXPECT_EQ(to_string(r.why), to_string(why));
  EXPECT_EQ(to_string(r.reason), to_string(reason));
}

TEST(MasterReceipts, SayWhatWasTakenAndWhyTheRestWasIgnored) {
  Master<> m(MasterConfig{}, 0);
  expect_receipt(m.handle_datagram("1:x:3:5:ACTIVE", 9, 1), Action::Ignore, MasterIgnored::malformed, Reason::bad_number);
  EXPECT_EQ(m.rejected(), 1u);
  expect_receipt(m.handle_datagram("5:7:3:5:ACTIVE", 9, 2), Action::Ignore, MasterIgnored::misaddressed);
  expect_receipt(m.handle_datagram("5:1:3:6:2", 9, 3), Action::Ignore, MasterIgnored::unexpected_type);  // PONG
  expect_receipt(m.handle_datagram("5:1:4:5:ACTIVE", 9, 4), Action::MasterPing, MasterIgnored::unknown_sender);
  EXPECT_TRUE(sent(m).empty()) << "no PONG to an id not registered";
  expect_receipt(m.handle_datagram("5:1:5:3:1", 9, 5), Action::MasterAnswer, MasterIgnored::unknown_sender);
  expect_receipt(m.handle_datagram("5:1:6:20:x", 9, 6), Action::MasterReport, MasterIgnored::unknown_sender);

  expect_receipt(m.handle_datagram("50001:0:1:1:A", 11, 10), Action::MasterSync, MasterIgnored::none);
  EXPECT_EQ(sent(m), std::vector<std::string>{"1:2:1:2:50001"});
  expect_receipt(m.handle_datagram("2:1:2:3:99", 11, 11), Action::MasterAnswer, MasterIgnored::stale_answer);
  expect_receipt(m.handle_datagram("2:1:3:3:1", 11, 12), Action::MasterAnswer, MasterIgnored::none);
  expect_receipt(m.handle_datagram("2:1:3:3:1", 11, 13), Action::MasterAnswer, MasterIgnored::stale_answer);
  expect_receipt(m.handle_datagram("2:1:4:5:ACTIVE", 11, 14), Action::MasterPing, MasterIgnored::none);
  EXPECT_EQ(sent(m), std::vector<std::string>{"1:2:2:6:4"});
  expect_receipt(m.handle_datagram("2:1:5:20:x", 11, 15), Action::MasterReport, MasterIgnored::none);
  expect_receipt(m.handle_datagram("2:1:5:20:x", 11, 16), Action::MasterReport, MasterIgnored::duplicate);
}

TEST(MasterSync, KeepsTheModelAndTheDevicesAnnounced) {
  Master<> m(MasterConfig{}, 0);
  m.handle_datagram("50001:0:1:1:A:left motor:right motor:colour sensor", 11, 1);
  m.handle_datagram("50002:0:1:1:B", 12, 2);
  m.handle_datagram("50003:0:1:19", 13, 3);  // PANIC: registered, nothing announced
  ASSERT_EQ(m.registry().size(), 3u);
  EXPECT_EQ(m.registry().at(2).model, "A");
  EXPECT_EQ(m.registry().at(2).devices, (std::vector<std::string>{"left motor", "right motor", "colour sensor"}));
  EXPECT_EQ(m.registry().at(3).model, "B");
  EXPECT_TRUE(m.registry().at(3).devices.empty());
  EXPECT_EQ(m.registry().at(4).model, "");
  EXPECT_TRUE(m.registry().at(4).devices.empty());
}

TEST(MasterCommand, ReturnsTheAgentsItQueuedTheCommandFor) {
  Master<> m(MasterConfig{}, 0);
  m.handle_datagram("50009:0:1:1:A", 11, 1);
  m.handle_datagram("50008:0:1:1:A", 12, 2);
  EXPECT_EQ(m.command(0, Command::simple(MsgType::START), 3), (std::vector<std::uint16_t>{2, 3}));
  EXPECT_EQ(m.command(3, Command::simple(MsgType::STOP), 4), (std::vector<std::uint16_t>{3}));
  EXPECT_TRUE(m.command(7, Command::simple(MsgType::STOP), 5).empty()) << "an unknown id";
  EXPECT_EQ(m.registry().at(3).queue.size(), 2u);
  Master<> none(MasterConfig{}, 0);
  EXPECT_TRUE(none.command(0, Command::simple(MsgType::START), 1).empty()) << "all of no agent";
}

TEST(MasterMsgids, AnAgentWhoseMsgidsWrapIsStillHeardFresh) {
  // The master orders an agent's msgids as the agent orders the master's: serial-number order
  // (msgid_newer). An agent whose msgid wraps from 4294967295 to 0 is heard fresh; a late copy of
  // one sent before the wrap is stale.
  Master<> m(MasterConfig{}, 0);
  m.handle_datagram("50001:0:4294967294:1:A", 11, 1);
  EXPECT_EQ(sent(m), std::vector<std::string>{"1:2:1:2:50001"});
  expect_receipt(m.handle_datagram("2:1:4294967295:3:1", 11, 2), Action::MasterAnswer, MasterIgnored::none);
  EXPECT_EQ(m.registry().at(2).last_msgid, 4294967295u);
  m.handle_datagram("2:1:0:5:WORKING", 11, 3);  // after the wrap: fresh, its state is news
  EXPECT_EQ(m.registry().at(2).last_msgid, 0u);
  EXPECT_TRUE(m.registry().at(2).has_state);
  EXPECT_EQ(m.registry().at(2).state, AgentState::WORKING);
  m.handle_datagram("2:1:4294967295:5:PAUSED", 11, 4);  // a copy from before the wrap: stale
  EXPECT_EQ(m.registry().at(2).last_msgid, 0u);
  EXPECT_EQ(m.registry().at(2).state, AgentState::WORKING);
  m.handle_datagram("2:1:1:5:PAUSED", 11, 5);
  EXPECT_EQ(m.registry().at(2).last_msgid, 1u);
  EXPECT_EQ(m.registry().at(2).state, AgentState::PAUSED);
}

TEST(MasterReady, WritesTheStateBeforeWhatDependsOnIt) {
  MasterConfig c;
  c.next_msgid = 100;
  c.durable_first = true;
  Master<> m(c, 0);
  std::vector<std::string> done;
  bool disk_ok = true;
  auto write = [&](const MasterDurable& d) {
    done.push_back("write " + std::string(durable_text(d).view()));
    return disk_ok;
  };
  auto send = [&](const MasterTransmit& t) { done.push_back(t.bytes); };
  EXPECT_TRUE(m.ready(write, send));
  EXPECT_EQ(done, std::vector<std::string>{"write next_id=2\nnext_msgid=4196\nepoch=1\nmembers=\nmembers_epoch=1\n"})
      << "the first ready() writes, the msgid block reserved from 100";
  done.clear();
  m.handle_datagram("50001:0:1:1:A", 11, 1);  // a new agent: id 2 given, next_id 3
  MasterTransmit t;
  EXPECT_FALSE(m.poll_transmit(t)) << "durable_first: MASTER waits for next_id on disk";
  disk_ok = false;
  EXPECT_FALSE(m.ready(write, send));
  EXPECT_EQ(done.size(), 1u) << "the write failed: nothing sent";
  disk_ok = true;
  done.clear();
  EXPECT_TRUE(m.ready(write, send));
  EXPECT_EQ(done, (std::vector<std::string>{"write next_id=3\nnext_msgid=4197\nepoch=1\nmembers=\nmembers_epoch=1\n",
                                            "1:2:100:2:50001"}));
  // Msgids within the block need no write until half of it is used.
  done.clear();
  m.handle_datagram("2:1:2:3:100", 11, 2);  // ACK of MASTER
  std::uint32_t mid = 3;
  for (std::uint32_t i = 0; i < kMsgidBlock / 2 - 1; ++i)  // PINGs: a PONG each, msgids 101..2147
    m.handle_datagram("2:1:" + std::to_string(mid++) + ":5:ACTIVE", 11, 3);
  EXPECT_TRUE(m.ready(write, send));
  EXPECT_EQ(done.size(), kMsgidBlock / 2 - 1) << "PONGs only: no write yet";
  EXPECT_EQ(m.next_msgid(), 2148u);
  done.clear();
  m.handle_datagram("2:1:" + std::to_string(mid++) + ":5:ACTIVE", 11, 4);
  EXPECT_TRUE(m.ready(write, send));
  ASSERT_FALSE(done.empty());
  EXPECT_EQ(done.front().substr(0, 6), "write ") << "half the block used: the next one reserved";
}

TEST(MsgidReservation, LowWhenHalfTheBlockIsUsed) {
  MsgidReservation r;
  EXPECT_TRUE(r.low(1)) << "nothing reserved yet";
  EXPECT_EQ(r.reserve(4294967000u), 4294967000u + kMsgidBlock);  // wraps, in serial order
  EXPECT_FALSE(r.low(4294967000u + kMsgidBlock / 2 - 1));
  EXPECT_TRUE(r.low(4294967000u + kMsgidBlock / 2));
}

TEST(StartIds, DrawnFromTheRandomBits) {
  const StartIds a = draw_start_ids(0), b = draw_start_ids(~std::uint64_t{0});
  EXPECT_EQ(a.temp_id, kFirstTempId);
  EXPECT_EQ(a.first_msgid, 1u);
  EXPECT_GE(b.temp_id, kFirstTempId);
  EXPECT_GE(b.first_msgid, 1u);
  EXPECT_LE(b.first_msgid, 1000000000u);
  EXPECT_LT(b.first_msgid, kElectedMsgidBase);
}

TEST(MasterReceipts, CopiesReachTheHandlerUnlessDropCopiesIsOn) {
  Master<> spec(MasterConfig{}, 0);  // MasterLogic: every copy goes through its handler
  for (int copy = 0; copy < 3; ++copy)
    expect_receipt(spec.handle_datagram("50001:0:1:1:A", 11, 1), Action::MasterSync, MasterIgnored::none);
  EXPECT_EQ(sent(spec).size(), 3u) << "each copy of AGENT resends MASTER";

  MasterConfig c;
  c.drop_copies = true;
  Master<> program(c, 0);
  expect_receipt(program.handle_datagram("50001:0:1:1:A", 11, 1), Action::MasterSync, MasterIgnored::none);
  expect_receipt(program.handle_datagram("50001:0:1:1:A", 11, 1), Action::Ignore, MasterIgnored::duplicate);
  expect_receipt(program.handle_datagram("50001:0:1:1:A", 11, 2), Action::Ignore, MasterIgnored::duplicate);
  expect_receipt(program.handle_datagram("9:7:1:5:ACTIVE", 11, 3), Action::Ignore, MasterIgnored::misaddressed);
  expect_receipt(program.handle_datagram("50001:0:2:1:A", 11, 4), Action::MasterSync, MasterIgnored::none);
  EXPECT_EQ(sent(program).size(), 2u);
}

TEST(MasterReceipts, HandleMessageTakesADecodedDatagramAsHandleDatagramDoes) {
  const char* input[] = {"50001:0:1:1:A", "2:1:2:3:1", "2:1:3:5:ACTIVE", "2:1:4:20:x", "2:1:5:6:1"};
  Master<> a(MasterConfig{}, 0), b(MasterConfig{}, 0);
  Millis t = 0;
  for (const char* d : input) {
    Message msg;
    ASSERT_TRUE(decode(d, msg).ok());
    const MasterReceipt ra = a.handle_datagram(d, 11, ++t);
    const MasterReceipt rb = b.handle_message(msg, d, 11, t);
    EXPECT_EQ(ra.action, rb.action) << d;
    EXPECT_EQ(ra.why, rb.why) << d;
    EXPECT_EQ(sent(a), sent(b)) << d;
  }
  EXPECT_EQ(a.registry().size(), 1u);
  EXPECT_EQ(a.next_deadline(), b.next_deadline());
}

TEST(MasterReceipts, ElectionReasons) {
  // An elected agent's master (id 7, epoch 2, members 7 8 9) gives no ids.
  Master<> m(MasterConfig::for_elected_agent(Timers{}, 7, 2, {7, 8, 9}), 0);
  sent(m);
  expect_receipt(m.handle_datagram("50001:0:1:1:A", 11, 1), Action::MasterSync, MasterIgnored::ids_exhausted);
  expect_receipt(m.handle_datagram("7:0:1003:29:2:7:8:9", 11, 2), Action::Ignore, MasterIgnored::own_broadcast);
  expect_receipt(m.handle_datagram("8:7:5:28:1:8", 12, 3), Action::Ignore, MasterIgnored::not_enabled);  // VOTE: not standing
  expect_receipt(m.handle_datagram("8:7:6:5:ACTIVE", 12, 4), Action::MasterPing, MasterIgnored::none);  // a member: adopted
  EXPECT_EQ(m.registry().count(8), 1u);
  expect_receipt(m.handle_datagram("1:7:1:30:3", 1, 5), Action::HandleStale, MasterIgnored::none);  // epoch 3: step down
  EXPECT_EQ(m.role(), MasterRole::stepped_down);
  expect_receipt(m.handle_datagram("8:7:7:5:ACTIVE", 12, 6), Action::Ignore, MasterIgnored::not_master);
}

}  // namespace

namespace {

TEST(MasterRegistry, ACopyFindsItsOwnEntries) {
  // The conformance driver snapshots a Master by copying it: the copy's id index must point into
  // the copy, so that changing one leaves the other as it was.
  Master<> a(MasterConfig{}, 0);
  a.handle_datagram("50001:0:1:1:A", 11, 1);
  a.handle_datagram("2:1:2:3:1", 11, 2);
  Master<> b = a;
  b.handle_datagram("2:1:3:5:WORKING", 11, 3);
  EXPECT_FALSE(a.registry().at(2).has_state);
  EXPECT_EQ(b.registry().at(2).state, AgentState::WORKING);
  a = b;
  b.handle_datagram("2:1:4:5:PAUSED", 11, 4);
  EXPECT_EQ(a.registry().at(2).state, AgentState::WORKING);
  EXPECT_EQ(b.registry().at(2).state, AgentState::PAUSED);
  a.handle_datagram("2:1:5:5:ACTIVE", 11, 5);  // through a's index, into a's entry
  EXPECT_EQ(a.registry().at(2).state, AgentState::ACTIVE);
  EXPECT_EQ(b.registry().at(2).state, AgentState::PAUSED);
}

}  // namespace
