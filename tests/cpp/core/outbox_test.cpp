// The agent's outbox (agent_outbox.hpp): msgids, the RELAY envelope, the oldest dropped when full,
// and a refused encoding that changes nothing.
#include <gtest/gtest.h>

#include <string>
#include <string_view>

#include "ev3proto/agent_outbox.hpp"

namespace ev3proto {
namespace {

std::string poll_one(AgentOutbox<2, 64>& box, Transmit& t) {
  EXPECT_TRUE(box.poll(t, 77));
  return std::string(t.bytes);
}

TEST(Outbox, StampsMsgidsAndSendsToTheMastersPeer) {
  AgentOutbox<2, 64> box(10);
  const std::string_view p[1] = {"ACTIVE"};
  ASSERT_TRUE(box.emit(5, Dest::master, 1, MsgType::PING, p, 1, 0, 0));
  EXPECT_EQ(box.next_msgid(), 11u);
  Transmit t;
  EXPECT_EQ(poll_one(box, t), "5:1:10:5:ACTIVE");
  EXPECT_EQ(t.dest, Dest::master);
  EXPECT_EQ(t.peer, 77u);
  EXPECT_FALSE(box.poll(t, 77));
}

TEST(Outbox, RelayedTheMastersDatagramTravelsInsideRelayWithItsMsgid) {
  AgentOutbox<2, 64> box(10);
  const std::string_view p[1] = {"ACTIVE"};
  ASSERT_TRUE(box.emit(5, Dest::master, 1, MsgType::PING, p, 1, 0, 3));
  Transmit t;
  const std::string outer = poll_one(box, t);
  EXPECT_EQ(outer.rfind("5:3:10:", 0), 0u) << outer;
  EXPECT_NE(outer.find(":5%3A1%3A10%3A5%3AACTIVE"), std::string::npos) << outer;  // escaped inside
}

TEST(Outbox, FullDropsTheOldestAndARefusedEnvelopeLeavesTheQueueAsItWas) {
  AgentOutbox<2, 64> box(10);
  ASSERT_TRUE(box.emit(5, Dest::broadcast, 0, MsgType::PANIC, nullptr, 0, 0, 0));
  ASSERT_TRUE(box.emit(5, Dest::broadcast, 0, MsgType::PANIC, nullptr, 0, 0, 0));
  // fits alone (64 bytes), not inside RELAY: refused, nothing queued, no msgid taken
  const std::string big(50, 'x');
  const std::string_view b[1] = {big};
  EXPECT_FALSE(box.emit(5, Dest::master, 1, MsgType::PING, b, 1, 0, 3));
  EXPECT_EQ(box.next_msgid(), 12u);
  EXPECT_EQ(box.overflowed(), 0u);
  Transmit t;
  EXPECT_EQ(poll_one(box, t), "5:0:10:19");
  EXPECT_EQ(poll_one(box, t), "5:0:11:19");
  // full: the third drops the oldest and counts it
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(box.emit(5, Dest::broadcast, 0, MsgType::PANIC, nullptr, 0, 0, 0));
  EXPECT_EQ(box.overflowed(), 1u);
  EXPECT_EQ(poll_one(box, t), "5:0:13:19");
}

}  // namespace
}  // namespace ev3proto
