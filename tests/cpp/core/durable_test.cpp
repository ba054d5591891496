// The durable state as a file keeps it (ev3proto/durable.hpp): the text round-trips, the files the
// programs write read back, and every refusal of the one rule names its key.
#include <gtest/gtest.h>

#include <string>

#include "ev3proto/durable.hpp"

namespace {

using namespace ev3proto;

Durable agent_state(std::uint32_t epoch, std::uint16_t voted, std::uint32_t mepoch, std::uint32_t floor,
                    std::initializer_list<std::uint16_t> ids) {
  Durable d;
  d.epoch = epoch;
  d.voted_for = voted;
  d.mepoch = mepoch;
  d.floor = floor;
  for (std::uint16_t id : ids) d.members[d.member_count++] = id;
  return d;
}

/// A stored state's text and the refusal it gets.
struct Refusal {
  std::string text;
  const char* said;
};

TEST(Durable, AgentStateRoundTrips) {
  const Durable d = agent_state(5, 7, 4, 5, {7, 8, 9});
  const DurableText t = durable_text(d);
  EXPECT_EQ(t.view(), "epoch=5\nvoted_for=7\nmembers=7,8,9\nmembers_epoch=4\nfloor=5\n");
  Durable back;
  DurableError err;
  ASSERT_TRUE(parse_durable(t.view(), back, err)) << err.view();
  EXPECT_EQ(back, d);
  EXPECT_TRUE(err.view().empty());
  // At its longest: every id and number at its widest fits the text.
  Durable big = agent_state(0xFFFFFFFFu, 65535, 0xFFFFFFFFu, 0xFFFFFFFFu, {});
  for (std::uint16_t id = 49999; big.member_count < kMaxMembership; --id) big.members[big.member_count++] = id;
  ASSERT_TRUE(parse_durable(durable_text(big).view(), back, err)) << err.view();
  EXPECT_EQ(back, big);
}

TEST(Durable, MasterStateRoundTrips) {
  MasterDurable d;
  d.next_id = 12;
  d.next_msgid = 1048576;
  d.epoch = 5;
  d.members_epoch = 4;
  for (std::uint16_t id : {std::uint16_t{7}, std::uint16_t{8}, std::uint16_t{9}}) d.members[d.member_count++] = id;
  const DurableText t = durable_text(d);
  EXPECT_EQ(t.view(), "next_id=12\nnext_msgid=1048576\nepoch=5\nmembers=7,8,9\nmembers_epoch=4\n");
  MasterDurable back;
  DurableError err;
  ASSERT_TRUE(parse_master_durable(t.view(), back, err)) << err.view();
  EXPECT_EQ(std::string(durable_text(back).view()), std::string(t.view()));
}

TEST(Durable, FilesOfTheProgramsReadBack) {
  // ev3-agent wrote its keys in name order; keys may come in any order, comments and lines without
  // '=' are skipped, unknown keys ignored, the last of a repeated key counts.
  Durable d;
  DurableError err;
  ASSERT_TRUE(parse_durable("epoch=3\nfloor=3\nmembers=2,3\nmembers_epoch=2\nvoted_for=2\n", d, err)) << err.view();
  EXPECT_EQ(d, agent_state(3, 2, 2, 3, {2, 3}));
  ASSERT_TRUE(parse_durable("# agent\nepoch=1\n\nvoted_for=0\nnote=x\nepoch=2\n", d, err)) << err.view();
  EXPECT_EQ(d, agent_state(2, 0, 0, 0, {}));  // no membership keys: none known
  ASSERT_TRUE(parse_durable("epoch=2\nvoted_for=0\nmembers=\nmembers_epoch=\nfloor=\n", d, err)) << err.view();
  EXPECT_EQ(d, agent_state(2, 0, 0, 0, {}));
  MasterDurable m;
  ASSERT_TRUE(parse_master_durable("epoch=4\nmembers=\nmembers_epoch=1\nnext_id=5\nnext_msgid=100\n", m, err))
      << err.view();
  EXPECT_EQ(m.next_id, 5u);
  EXPECT_EQ(m.next_msgid, 100u);
  EXPECT_EQ(m.epoch, 4u);
  EXPECT_EQ(m.members_epoch, 1u);
  EXPECT_EQ(m.member_count, 0u);
  ASSERT_TRUE(parse_master_durable("next_id=5\nnext_msgid=100\nepoch=4\n", m, err)) << err.view();
  EXPECT_EQ(m.members_epoch, 0u);
}

TEST(Durable, EachRefusalNamesItsKey) {
  const std::string many = [] {
    std::string s;
    for (int id = 2; id < 33; ++id) s += (s.empty() ? "" : ",") + std::to_string(id);  // 31 ids
    return s;
  }();
  const Refusal refused[] = {
      {"voted_for=0\n", "epoch: missing"},
      {"epoch=0\nvoted_for=0\n", "epoch: '0' is not a number 1..4294967295"},
      {"epoch=x\nvoted_for=0\n", "epoch: 'x' is not a number 1..4294967295"},
      {"epoch=03\nvoted_for=0\n", "epoch: '03' is not a number 1..4294967295"},
      {"epoch=3\n", "voted_for: missing"},
      {"epoch=3\nvoted_for=65536\n", "voted_for: '65536' is not a number 0..65535"},
      {"epoch=3\nvoted_for=0\nmembers=7,x\nmembers_epoch=1\nfloor=1\n",
       "members: '7,x' is not a list of at most 30 agent ids, comma-separated"},
      {"epoch=3\nvoted_for=0\nmembers=7,\nmembers_epoch=1\nfloor=1\n",
       "members: '7,' is not a list of at most 30 agent ids, comma-separated"},
      {"epoch=3\nvoted_for=0\nmembers=" + many + "\nmembers_epoch=1\nfloor=1\n",
       "members: '2,3,4,5,6,7,8,9,10,11,12,13,14,15,16,17,...' is not a list of at most 30 agent ids, "
       "comma-separated"},
      {"epoch=3\nvoted_for=0\nmembers=7,1\nmembers_epoch=1\nfloor=1\n", "members: 1 is not an agent id 2..49999"},
      {"epoch=3\nvoted_for=0\nmembers=50001\nmembers_epoch=1\nfloor=1\n", "members: 50001 is not an agent id 2..49999"},
      {"epoch=3\nvoted_for=0\nmembers=7,8,7\nmembers_epoch=1\nfloor=1\n", "members: 7 is listed twice"},
      {"epoch=3\nvoted_for=0\nmembers=7\nmembers_epoch=x\nfloor=1\n", "members_epoch: 'x' is not a number"},
      {"epoch=5\nvoted_for=0\nmembers=7\nmembers_epoch=7\nfloor=5\n", "members_epoch: 7 is above epoch 5"},
      {"epoch=3\nvoted_for=0\nmembers=7\n",
       "members_epoch: missing, but members lists agents (the epoch that published them is needed)"},
      {"epoch=3\nvoted_for=0\nmembers=7\nmembers_epoch=0\nfloor=0\n",
       "members_epoch: 0, but members lists agents (the epoch that published them is needed)"},
      {"epoch=3\nvoted_for=0\nmembers=7\nmembers_epoch=2\nfloor=x\n", "floor: 'x' is not a number 0..4294967295"},
      {"epoch=3\nvoted_for=0\nmembers=7\nmembers_epoch=2\nfloor=4\n", "floor: 4 is above epoch 3"},
      {"epoch=3\nvoted_for=0\nmembers=7\nmembers_epoch=2\nfloor=1\n",
       "floor: 1 is below members_epoch 2 (learning a membership raises the floor to its epoch)"},
      {"epoch=3\nvoted_for=0\nmembers=7\nmembers_epoch=2\n",
       "floor: 0 is below members_epoch 2 (learning a membership raises the floor to its epoch)"},
  };
  for (const Refusal& c : refused) {
    Durable d = agent_state(9, 9, 9, 9, {9});
    DurableError err;
    EXPECT_FALSE(parse_durable(c.text, d, err)) << c.text;
    EXPECT_EQ(err.view(), c.said) << c.text;
    EXPECT_EQ(d, Durable{}) << "a refused state leaves the defaults";
  }
}

TEST(Durable, TheMastersStateByTheSameMembershipRule) {
  const Refusal refused[] = {
      {"next_msgid=1\nepoch=1\n", "next_id: missing"},
      {"next_id=1\nnext_msgid=1\nepoch=1\n", "next_id: '1' is not a number 2..65535"},
      {"next_id=2\nnext_msgid=0\nepoch=1\n", "next_msgid: '0' is not a number 1..4294967295"},
      {"next_id=2\nnext_msgid=1\n", "epoch: missing"},
      {"next_id=5\nnext_msgid=100\nepoch=4\nmembers=2,3,4\n",
       "members_epoch: missing, but members lists agents (the epoch that published them is needed)"},
      {"next_id=5\nnext_msgid=100\nepoch=4\nmembers=2,3,4\nmembers_epoch=5\n", "members_epoch: 5 is above epoch 4"},
      {"next_id=5\nnext_msgid=100\nepoch=4\nmembers=2,3,2\nmembers_epoch=4\n", "members: 2 is listed twice"},
      {"next_id=5\nnext_msgid=100\nepoch=4\nmembers=2,x\nmembers_epoch=4\n",
       "members: '2,x' is not a list of at most 30 agent ids, comma-separated"},
  };
  for (const Refusal& c : refused) {
    MasterDurable d;
    DurableError err;
    EXPECT_FALSE(parse_master_durable(c.text, d, err)) << c.text;
    EXPECT_EQ(err.view(), c.said) << c.text;
  }
}

TEST(Durable, TheRuleOnTheStructs) {
  // What a program holds is checked by the same rule as what it reads (check_durable).
  DurableError err;
  EXPECT_TRUE(check_durable(agent_state(5, 0, 4, 4, {7}), err)) << err.view();
  EXPECT_TRUE(check_durable(Durable{}, err)) << err.view();
  const struct {
    Durable d;
    const char* said;
  } refused[] = {
      {agent_state(5, 0, 3, 2, {7}),
       "floor: 2 is below members_epoch 3 (learning a membership raises the floor to its epoch)"},
      {agent_state(5, 0, 3, 6, {7}), "floor: 6 is above epoch 5"},
      {agent_state(5, 0, 6, 6, {7}), "members_epoch: 6 is above epoch 5"},
      {agent_state(5, 0, 0, 0, {7}),
       "members_epoch: 0, but members lists agents (the epoch that published them is needed)"},
      {agent_state(0, 0, 0, 0, {}), "epoch: 0 is not a number 1..4294967295"},
  };
  for (const auto& c : refused) {
    err.clear();
    EXPECT_FALSE(check_durable(c.d, err)) << c.said;
    EXPECT_EQ(err.view(), c.said);
  }
  MasterDurable m;
  m.next_id = 1;
  err.clear();
  EXPECT_FALSE(check_master_durable(m, err));
  EXPECT_EQ(err.view(), "next_id: 1 is not a number 2..65535");
}

}  // namespace
