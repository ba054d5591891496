// The C++ message table must equal docs/messages.tsv row by row.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "ev3proto/messages.hpp"

namespace {

using namespace ev3proto;

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string cur;
  std::istringstream in(s);
  while (std::getline(in, cur, sep)) out.push_back(cur);
  if (!s.empty() && s.back() == sep) out.emplace_back();
  return out;
}

// The row as the TSV spells it, from the C++ table.
std::vector<std::string> row_of(const MessageSpec& s) {
  std::string params;
  for (std::size_t i = 0; i < s.declared; ++i) {
    if (i) params += ",";
    params += std::string(to_string(s.params[i].kind)) + ":" + std::string(s.params[i].name);
  }
  if (s.last_repeats) params += "...";
  if (params.empty()) params = "-";
  return {std::to_string(s.type), std::string(s.name), std::string(to_string(s.direction)),
          std::to_string(s.min_params), std::to_string(s.max_params), params};
}

TEST(MessageTable, EqualsDocsMessagesTsvRowByRow) {
  std::ifstream in(EV3_MESSAGES_TSV);
  ASSERT_TRUE(in) << "cannot open " << EV3_MESSAGES_TSV;
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    rows.push_back(split(line, '\t'));
  }
  ASSERT_EQ(rows.size(), kMessageTableSize) << "the TSV and the C++ table have different row counts";
  for (std::size_t r = 0; r < rows.size(); ++r) {
    ASSERT_EQ(rows[r].size(), 6u) << "TSV row " << r << " does not have 6 columns";
    EXPECT_EQ(row_of(kMessageTable[r]), rows[r]) << "row " << r << " (type " << rows[r][0] << ")";
  }
}

TEST(MessageTable, LookupByType) {
  for (const MessageSpec& s : kMessageTable) {
    ASSERT_NE(find_spec(s.type), nullptr);
    EXPECT_EQ(find_spec(s.type)->name, s.name);
    EXPECT_EQ(to_string(static_cast<MsgType>(s.type)), s.name);
  }
  EXPECT_EQ(find_spec(std::uint8_t{0}), nullptr);
  EXPECT_EQ(find_spec(std::uint8_t{34}), nullptr);
  EXPECT_EQ(find_spec(std::uint8_t{255}), nullptr);
  EXPECT_EQ(find_spec(std::uint8_t{43}), nullptr);
  EXPECT_EQ(kMessageTableSize, 36u);
}

TEST(MessageTable, EnumMatchesTable) {
  static_assert(find_spec(MsgType::PING)->name == "PING");
  static_assert(find_spec(MsgType::EVENT)->max_params == 32);
  static_assert(find_spec(MsgType::SENSOR_VALUE)->kind(31) == ParamKind::text);
  static_assert(find_spec(MsgType::NOT)->kind(0) == ParamKind::u32);
  EXPECT_EQ(to_string(MsgType::ACTION_INTERR), "ACTION_INTERR");
  EXPECT_EQ(to_string(MsgType::AGENT), "AGENT");
  EXPECT_EQ(to_string(MsgType::PANIC), "PANIC");
}

TEST(MessageTable, States) {
  AgentState s = AgentState::IDLE;
  for (const char* name : {"IDLE", "ACTIVE", "WORKING", "PAUSED", "PANIC"}) {
    ASSERT_TRUE(parse_state(name, s)) << name;
    EXPECT_EQ(to_string(s), name);
  }
  EXPECT_FALSE(parse_state("working", s));
  EXPECT_FALSE(parse_state("", s));
  EXPECT_FALSE(parse_state("IDLE ", s));
}

} // namespace
