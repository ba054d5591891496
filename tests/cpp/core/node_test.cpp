// The robot node (node.hpp): what handle_datagram reports, the events of the raft-Ready kind (only
// when something changed, durable first), the Master core's life (started when the agent core wins
// an epoch, fed the first copy of each datagram, dropped once it stepped down).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "fixed_timers.hpp"
#include "ev3proto/node.hpp"
#include "symbolic.hpp"

namespace {
using namespace ev3proto;

constexpr BehaviourSpec kNodeBehs[] = {{"explore", 1u}};

Node<>::Config config(bool election) {
  Node<>::Config c;
  c.agent.timers = ev3test::fixed_timers();
  c.agent.caps = Capabilities{"A", kNodeBehs, 1, 1u};
  c.agent.temp_id = 50001;
  c.agent.election.enabled = election;
  c.agent.election.score = 5;
  return c;
}

std::vector<std::string> events(Node<>& n) {
  std::vector<std::string> out;
  NodeEvent e;
  while (n.poll_event(e)) {
    std::string l(to_string(e.kind));
    if (e.kind == NodeEvent::Kind::durable) {
      l += " " + std::to_string(e.durable.epoch) + "/" + std::to_string(e.durable.voted_for) + " [";
      for (std::size_t i = 0; i < e.durable.member_count; ++i) l += (i ? "," : "") + std::to_string(e.durable.members[i]);
      l += "]@" + std::to_string(e.durable.mepoch) + " floor " + std::to_string(e.durable.floor);
    }
    if (e.kind == NodeEvent::Kind::role) l += " " + std::string(to_string(e.role)) + " " + std::to_string(e.epoch);
    if (e.kind == NodeEvent::Kind::leader) l += " " + std::to_string(e.leader) + "@" + std::to_string(e.epoch);
    if (e.kind == NodeEvent::Kind::master_started || e.kind == NodeEvent::Kind::master_stopped)
      l += " " + std::to_string(e.epoch) + (e.handed_over ? " handed_over" : "");
    out.push_back(l);
  }
  return out;
}

std::vector<std::string> sent(Node<>& n) {
  std::vector<std::string> out;
  NodeTransmit t;
  while (n.poll_transmit(t)) out.push_back(std::string(t.from_master_core ? "M " : "") + ev3test::symbolic(t.bytes));
  return out;
}

TEST(NodeHandled, SaysWhyADatagramWasIgnored) {
  Node<> n(config(false), 0);
  NodeHandled h = n.handle_datagram("1:7:1", 1, 1);
  EXPECT_EQ(h.why(), Ignored::undecodable);
  EXPECT_FALSE(h.agent.decode.ok());
  EXPECT_EQ(n.rejected(), 1u);
  EXPECT_EQ(n.handle_datagram("1:9:1:2:50002", 1, 2).why(), Ignored::misaddressed);
  EXPECT_EQ(n.handle_datagram("3:50001:1:2:50001", 3, 3).why(), Ignored::foreign_sender);
  EXPECT_EQ(n.handle_datagram("3:0:1:19", 3, 4).why(), Ignored::foreign_sender);  // another's PANIC
  EXPECT_EQ(n.handle_datagram("1:50001:9:3:1", 1, 4).why(), Ignored::not_for_agent);  // an ACK
  EXPECT_EQ(n.handle_datagram("1:50001:2:6:1", 1, 5).why(), Ignored::ignored_in_state);  // PONG while IDLE
  EXPECT_EQ(n.handle_datagram("2:0:1:21:1:5", 2, 6).why(), Ignored::election_off);
  h = n.handle_datagram("1:7:3:2:50001", 1, 7);
  EXPECT_TRUE(h.agent.taken());
  EXPECT_EQ(h.agent.action, Action::RecvMaster);
  EXPECT_EQ(n.handle_datagram("1:7:3:2:50001", 1, 8).agent.action, Action::RecvDuplicate);
  EXPECT_EQ(events(n), (std::vector<std::string>{"state", "led", "leader 1@1"}));
  n.battery_low(9);
  events(n);
  EXPECT_EQ(n.handle_datagram("1:7:4:8", 1, 10).why(), Ignored::off);
}

TEST(NodeHandled, StaleEpochIsAnsweredAndSaid) {
  Node<> n(config(true), 0);
  n.handle_datagram("1:7:1:2:50001", 1, 1);
  EXPECT_EQ(events(n), (std::vector<std::string>{"state", "led", "leader 1@1"}));
  n.handle_datagram("2:0:1:29:3:2:2:7", 2, 2);  // LEADER of epoch 3 from agent 2: follow it
  EXPECT_EQ(events(n), (std::vector<std::string>{"durable 3/0 [2,7]@3 floor 3", "leader 2@3"}));
  sent(n);
  const NodeHandled h = n.handle_datagram("1:7:2:8", 1, 3);  // the PC's bare START: epoch 1
  EXPECT_EQ(h.why(), Ignored::stale_epoch);
  EXPECT_EQ(sent(n), (std::vector<std::string>{"7->1 EPOCH_STALE #2 3"}));
  EXPECT_TRUE(events(n).empty()) << "nothing changed: no event";
}

/// Wins epoch 2 with members 7, 8, 9 (the vote of 8), as agent_election_win.txt.
void win(Node<>& n) {
  n.advance(1000);
  n.handle_datagram("1:7:20:2:50001", 1, 1000);
  n.handle_datagram("1:0:21:29:1:1:7:8:9", 1, 1000);
  n.advance(4000);                            // PANIC, relay requests
  n.handle_datagram("8:7:2:33:1", 8, 4000);   // PREVOTE_OK: with itself 2 of 3
  n.advance(7543);                            // StartElection (epoch 2)
  n.handle_datagram("8:7:3:28:2:7", 8, 7543); // VOTE: BecomeMaster
}

TEST(Node, AnElectedMasterCoreStartsAboveEveryEpochWonBefore) {
  // Followers ignore a command below a msgid they remember from the same id (AgentLogic Stale), so a
  // node elected again after a restart must not start lower than it sent before. Its Master core's
  // first msgid comes from the epoch won, not from the agent core's msgids (drawn at random at
  // every start): two lives with different agent-core msgids, the same Master-core msgids.
  for (const std::uint32_t first : {1u, 999999999u}) {
    Node<>::Config c = config(true);
    c.agent.first_msgid = first;
    Node<> n(c, 0);
    win(n);
    ASSERT_NE(n.master(), nullptr);
    EXPECT_EQ(n.master()->next_msgid(), elected_master_first_msgid(2) + 1) << first;  // its first LEADER
    EXPECT_LT(n.agent().next_msgid(), kElectedMsgidBase) << "the agent core's msgids stay below the Master core's";
  }
  // Epoch 3's block starts above all of epoch 2's; the blocks come round after kElectedMsgidEpochs.
  EXPECT_TRUE(msgid_newer(elected_master_first_msgid(3), elected_master_first_msgid(2) + kElectedMsgidsPerEpoch - 1));
  EXPECT_TRUE(msgid_newer(elected_master_first_msgid(kElectedMsgidEpochs + 1), elected_master_first_msgid(kElectedMsgidEpochs)));
  EXPECT_EQ(elected_master_first_msgid(kElectedMsgidEpochs + 2), elected_master_first_msgid(2));
}

TEST(Msgids, SerialOrderAndTheMastersSeed) {
  EXPECT_TRUE(msgid_newer(2, 1));
  EXPECT_FALSE(msgid_newer(1, 1));
  EXPECT_FALSE(msgid_newer(1, 2));
  EXPECT_TRUE(msgid_newer(0, 0xFFFFFFFFu)) << "past the wrap";
  EXPECT_TRUE(msgid_newer(5, 0xFFFFFFF0u));
  EXPECT_FALSE(msgid_newer(0xFFFFFFF0u, 5));
  EXPECT_FALSE(msgid_newer(0x80000001u, 1)) << "2^31 apart: not newer either way";
  EXPECT_FALSE(msgid_newer(1, 0x80000001u));
  // ev3-master without a state file: one msgid per ms of the wall clock, so a run started later
  // starts above an earlier one that sent fewer msgids than ms passed (also across 2^32).
  const std::uint64_t t0 = 1764160000000ull;  // 2025-11-26
  EXPECT_TRUE(msgid_newer(master_msgid_seed(t0 + 1000), master_msgid_seed(t0) + 999));
  EXPECT_TRUE(msgid_newer(master_msgid_seed(0x100000005ull), master_msgid_seed(0xFFFFFFFFull)));
  EXPECT_EQ(master_msgid_seed(0x100000000ull), 1u) << "never 0";
}

TEST(Node, RunsAMasterCoreWhileMasterAndReportsEachChangeOnce) {
  Node<> n(config(true), 0);
  win(n);
  // Drained once at the end: the agent core's events of all the calls, then the node's.
  const std::vector<std::string> ev = events(n);
  // The membership is durable too: learned from the PC's LEADER (epoch 1), then, once master, of
  // its own epoch (mepoch and floor 2).
  EXPECT_EQ(ev, (std::vector<std::string>{"state", "led", "state", "led", "leader 1@1", "durable 1/0 [7,8,9]@1 floor 1",
                                          "leader 0@0", "durable 2/7 [7,8,9]@1 floor 1", "role candidate 2",
                                          "durable 2/7 [7,8,9]@2 floor 2", "role master 2", "master_started 2"}));
  ASSERT_NE(n.master(), nullptr);
  EXPECT_EQ(n.master()->epoch(), 2u);
  EXPECT_EQ(n.master()->self_id(), 7u);
  EXPECT_EQ(n.master()->next_msgid(), elected_master_first_msgid(2) + 1);  // its first LEADER, above epoch 1's block
  const std::vector<std::string> out = sent(n);
  ASSERT_FALSE(out.empty());
  EXPECT_EQ(out.back().substr(0, 2), "M ");  // the Master core's LEADER, after the agent core's
  // The Master core gets the first copy of a PING only; the agent core ignores PINGs.
  NodeHandled h = n.handle_datagram("8:7:5:5:ACTIVE", 8, 7600);
  EXPECT_EQ(h.master, Action::MasterPing);
  EXPECT_EQ(h.why(), Ignored::for_the_master_core);
  h = n.handle_datagram("8:7:5:5:ACTIVE", 8, 7601);
  EXPECT_TRUE(h.copy);
  EXPECT_EQ(h.master, Action::Ignore);
  EXPECT_EQ(h.why(), Ignored::foreign_sender);  // not from a master it follows (it is one)
  OperatorEvent oe;
  ASSERT_TRUE(n.poll_operator_event(oe));  // the Master core saw 8's state
  EXPECT_EQ(oe.kind, OperatorEvent::Kind::state);
  EXPECT_FALSE(n.poll_operator_event(oe));
  EXPECT_TRUE(n.command(8, Command::simple(MsgType::STOP), 7602));
  EXPECT_FALSE(n.poll_operator_event(oe));  // STOP queued and sent; no answer yet
  EXPECT_EQ(sent(n).back(), "M 7->8 EPOCH_CMD #" + std::to_string(n.master()->next_msgid() - 1) + " 2 [7->8 STOP #" +
                                std::to_string(n.master()->next_msgid() - 1) + "]");
  // A newer master (the PC in epoch 3): the agent core follows it, the Master core hands its fleet
  // over and is dropped.
  n.handle_datagram("1:0:50:29:3:1:7:8:9", 1, 7700);
  EXPECT_EQ(events(n), (std::vector<std::string>{"state", "led", "durable 3/0 [7,8,9]@3 floor 3", "role none 3", "leader 1@3",
                                                 "master_stopped 2 handed_over"}));
  EXPECT_EQ(n.master(), nullptr);
  // its HANDOVER goes out although the core is gone (it was lost with the core before)
  const std::vector<std::string> last = sent(n);
  ASSERT_FALSE(last.empty());
  EXPECT_EQ(last.front(), "M 7->1 HANDOVER #" + std::to_string(elected_master_first_msgid(2) + 3) + " 3 7 8 9");
  EXPECT_FALSE(n.command(8, Command::simple(MsgType::STOP), 7701));
}

TEST(Node, DurableComesBeforeTheVoteItGuards) {
  Node<> n(config(true), 0);
  n.handle_datagram("1:7:1:2:50001", 1, 1);
  n.handle_datagram("1:0:2:29:1:1:7:8:9", 1, 2);
  n.advance(4000);  // PANIC
  events(n);
  sent(n);
  // ELECT(2) of a weaker candidate that knows no membership (members_epoch 0, below our floor 1):
  // the epoch is adopted, the vote refused.
  n.handle_datagram("8:0:9:27:2:1:0", 8, 4001);
  EXPECT_EQ(events(n), (std::vector<std::string>{"durable 2/0 [7,8,9]@1 floor 1"}));
  EXPECT_EQ(sent(n), (std::vector<std::string>{}));
  n.handle_datagram("9:0:9:27:3:1:1", 9, 4001);  // ELECT(3) of one that knows the list of epoch 1
  EXPECT_EQ(events(n), (std::vector<std::string>{"durable 3/9 [7,8,9]@1 floor 1"}));
  EXPECT_EQ(sent(n), (std::vector<std::string>{"7->9 VOTE #7 3 9"}));
}

TEST(Node, ReadyWritesTheVoteBeforeSendingIt) {
  Node<> n(config(true), 0);
  std::vector<std::string> done;
  bool disk_ok = true;
  auto write = [&](const Durable& d) {
    done.push_back("write " + std::to_string(d.epoch) + "/" + std::to_string(d.voted_for));
    return disk_ok;
  };
  auto send = [&](const NodeTransmit& t) { done.push_back(ev3test::symbolic(t.bytes)); };
  n.handle_datagram("1:7:1:2:50001", 1, 1);
  n.handle_datagram("1:0:2:29:1:1:7:8:9", 1, 2);
  n.advance(4000);  // PANIC
  ASSERT_TRUE(n.ready(write, send));
  events(n);
  done.clear();
  n.handle_datagram("9:0:9:27:3:1:1", 9, 4001);  // ELECT(3): the vote for 9
  disk_ok = false;
  EXPECT_FALSE(n.ready(write, send));
  EXPECT_EQ(done, (std::vector<std::string>{"write 3/9"})) << "the write failed: the VOTE is held";
  NodeTransmit t;
  EXPECT_FALSE(n.poll_transmit(t)) << "not handed out as an event either: held";
  disk_ok = true;
  done.clear();
  EXPECT_TRUE(n.ready(write, send));
  EXPECT_EQ(done, (std::vector<std::string>{"write 3/9", "7->9 VOTE #7 3 9"}));
  done.clear();
  EXPECT_TRUE(n.ready(write, send));
  EXPECT_TRUE(done.empty()) << "nothing changed: nothing written, nothing sent";
  EXPECT_EQ(n.unrouted().to_master, 0u);
  // persist(): the write alone, as the durable event comes; ready() then only sends.
  n.handle_datagram("8:0:10:27:4:1:1", 8, 4001);  // ELECT(4): the vote for 8
  EXPECT_TRUE(n.persist(write));
  EXPECT_EQ(done, (std::vector<std::string>{"write 4/8"}));
  EXPECT_TRUE(n.ready(write, send));
  EXPECT_EQ(done, (std::vector<std::string>{"write 4/8", "7->8 VOTE #8 4 8"}));
}

}  // namespace
