// Reliable reports (ev3proto/reports.hpp, record.hpp): the agent's bounded buffer (count and bytes,
// the drop marker, what only the PC's acknowledgement frees, Send's window), the master's PCTake,
// and the record file's lines read back.
#include <gtest/gtest.h>

#include <map>
#include <string>
#include <vector>

#include "fixed_timers.hpp"
#include "ev3proto/agent.hpp"
#include "ev3proto/master.hpp"
#include "ev3proto/record.hpp"
#include "ev3proto/reports.hpp"

namespace {

using namespace ev3proto;

std::string report(int i) { return "7:1:" + std::to_string(i) + ":15:" + std::to_string(i); }

/// What next() offers until the window is full: "r3" (report 3) or "d1-4" (marker 1..4).
template <class B>
std::vector<std::string> window(B& b) {
  std::vector<std::string> out;
  bool marker = false;
  std::uint32_t seq = 0;
  std::string_view d;
  while (b.next(marker, seq, d)) {
    out.push_back(marker ? "d" + std::to_string(b.lo()) + "-" + std::to_string(seq) : "r" + std::to_string(seq));
    if (!marker) {
      EXPECT_EQ(std::string(d), report(static_cast<int>(seq)));
    }
    b.sent(seq);
  }
  return out;
}

TEST(ReportBuffer, NumbersFromOneAndKeepsUntilThePcAcknowledges) {
  ReportBuffer<8, 1024> b;
  for (int i = 1; i <= 3; ++i) EXPECT_EQ(b.Make(report(i)), static_cast<std::uint32_t>(i));
  EXPECT_EQ(b.held(), 3u);
  EXPECT_EQ(window(b), (std::vector<std::string>{"r1", "r2", "r3"}));
  // An interim master's acknowledgement frees nothing; it only stops the resending to it.
  EXPECT_TRUE(b.TakeAck(2, false, true));
  EXPECT_EQ(b.lo(), 1u);
  EXPECT_EQ(b.held(), 3u);
  b.retry();
  EXPECT_EQ(window(b), (std::vector<std::string>{"r3"}));
  // Another master: everything held goes to it again.
  b.new_master();
  EXPECT_EQ(window(b), (std::vector<std::string>{"r1", "r2", "r3"}));
  // The PC's frees, also when the agent reports elsewhere.
  EXPECT_TRUE(b.TakeAck(2, true, false));
  EXPECT_EQ(b.lo(), 3u);
  EXPECT_EQ(b.held(), 1u);
  // An acknowledgement of a number never made is not ours.
  EXPECT_FALSE(b.TakeAck(4, true, true));
  EXPECT_EQ(b.lo(), 3u);
}

TEST(ReportBuffer, TheWindowSendsFourAtATime) {
  ReportBuffer<16, 4096> b;
  for (int i = 1; i <= 7; ++i) b.Make(report(i));
  EXPECT_EQ(window(b), (std::vector<std::string>{"r1", "r2", "r3", "r4"}));
  b.TakeAck(2, true, true);
  EXPECT_EQ(window(b), (std::vector<std::string>{"r5", "r6"}));
  b.TakeAck(6, true, true);
  EXPECT_EQ(window(b), (std::vector<std::string>{"r7"}));
}

TEST(ReportBuffer, AFullBufferDropsTheOldestIntoOneMarker) {
  ReportBuffer<3, 1024> b;
  for (int i = 1; i <= 6; ++i) b.Make(report(i));
  EXPECT_EQ(b.held(), 3u);
  EXPECT_EQ(b.dropped(), 3u);
  EXPECT_EQ(b.lo(), 1u);
  EXPECT_EQ(b.mk(), 3u);
  // The marker goes first, as one datagram for 1..3, then the reports held.
  EXPECT_EQ(window(b), (std::vector<std::string>{"d1-3", "r4"}));
  b.TakeAck(3, true, true);
  EXPECT_EQ(window(b), (std::vector<std::string>{"r5", "r6"}));
  // The PC recorded the marker and 4: the marker is gone, 5 and 6 are held.
  b.TakeAck(4, true, true);
  EXPECT_EQ(b.lo(), 5u);
  EXPECT_EQ(b.mk(), 4u);
  EXPECT_EQ(b.held(), 2u);
}

TEST(ReportBuffer, ARunTimeLimitBelowTheCompiledOne) {
  ReportBuffer<16, 4096> b;
  b.set_limit(3);
  for (int i = 1; i <= 5; ++i) b.Make(report(i));
  EXPECT_EQ(b.held(), 3u);
  EXPECT_EQ(b.dropped(), 2u);
  b.set_limit(0);  // 0: the compiled bound
  for (int i = 6; i <= 20; ++i) b.Make(report(i));
  EXPECT_EQ(b.held(), 16u);
}

TEST(ReportBuffer, TheByteBoundDropsTooAndTheRingWraps) {
  ReportBuffer<100, 64> b;  // 64 bytes: at most 16 bytes a report
  const std::string r(12, 'x');
  std::uint32_t last = 0;
  for (int i = 0; i < 40; ++i) {
    last = b.Make(r);
    ASSERT_NE(last, 0u);
    EXPECT_LE(b.held() * r.size(), 64u);
    if (i >= 5) {
      EXPECT_EQ(b.held(), 5u);  // 5 fit in 64 bytes, also across the ring's end
    }
  }
  EXPECT_EQ(b.made(), 40u);
  EXPECT_EQ(b.dropped() + b.held(), 40u);
  EXPECT_EQ(b.Make(std::string(17, 'y')), 0u);  // longer than a quarter: refused, nothing changes
  EXPECT_EQ(b.made(), 40u);
  // Every report held reads back as it was made, across the wrap.
  b.new_master();
  bool marker = false;
  std::uint32_t seq = 0;
  std::string_view d;
  ASSERT_TRUE(b.next(marker, seq, d));
  EXPECT_TRUE(marker);
  b.sent(seq);
  while (b.next(marker, seq, d)) {
    EXPECT_EQ(std::string(d), r);
    b.sent(seq);
  }
}

TEST(PCTake, RecordsOnlyTheNextAndSaysWhatItDid) {
  ReportRecord r;
  std::uint32_t skipped = 0;
  EXPECT_EQ(PCTake(r, 2, 0, 1, skipped), ReportTaken::ahead);  // the record starts at first = 1
  EXPECT_EQ(r.stored(), 0u);
  EXPECT_EQ(r.ahead, 2u);
  EXPECT_EQ(PCTake(r, 1, 0, 1, skipped), ReportTaken::stored);
  EXPECT_EQ(PCTake(r, 1, 0, 1, skipped), ReportTaken::copy);
  EXPECT_EQ(PCTake(r, 2, 0, 1, skipped), ReportTaken::stored);
  EXPECT_EQ(r.ahead, 0u);
  EXPECT_EQ(PCTake(r, 3, 7, 3, skipped), ReportTaken::dropped);  // the marker 3..7
  EXPECT_EQ(r.dropped, 5u);
  EXPECT_EQ(PCTake(r, 3, 8, 3, skipped), ReportTaken::dropped);  // the marker grew: 8 too
  EXPECT_EQ(r.dropped, 6u);
  EXPECT_EQ(PCTake(r, 12, 0, 11, skipped), ReportTaken::ahead);  // 9, 10 no longer held: skipped
  EXPECT_EQ(skipped, 2u);
  EXPECT_EQ(r.skipped, 2u);
  EXPECT_EQ(r.stored(), 10u);
  EXPECT_EQ(PCTake(r, 0, 0, 1, skipped), ReportTaken::invalid);
  EXPECT_EQ(PCTake(r, 5, 0, 6, skipped), ReportTaken::invalid);
  EXPECT_EQ(r.reports, 2u);
}

TEST(PCTake, TheEntriesItMadeInTheOrderRecorded) {
  ReportRecord r;
  std::uint32_t skipped = 0;
  ReportRecord before = r;
  PCTake(r, 4, 0, 4, skipped);  // a new record starts at first = 4: report 4
  ReportEntries e = taken_entries(before, r);
  EXPECT_EQ(e.report, 4u);
  EXPECT_EQ(e.skipped + e.dropped, 0u);
  before = r;
  PCTake(r, 5, 9, 5, skipped);  // the marker 5..9
  e = taken_entries(before, r);
  EXPECT_EQ(e.report, 0u);
  EXPECT_EQ(e.dropped_from, 5u);
  EXPECT_EQ(e.dropped, 5u);
  before = r;
  PCTake(r, 5, 11, 5, skipped);  // the marker grew: only 10 and 11 are new
  e = taken_entries(before, r);
  EXPECT_EQ(e.dropped_from, 10u);
  EXPECT_EQ(e.dropped, 2u);
  before = r;
  PCTake(r, 14, 0, 14, skipped);  // 12 and 13 no longer held: skipped, then report 14
  e = taken_entries(before, r);
  EXPECT_EQ(e.skipped_from, 12u);
  EXPECT_EQ(e.skipped, 2u);
  EXPECT_EQ(e.report, 14u);
  EXPECT_EQ(e.dropped, 0u);
  before = r;
  PCTake(r, 14, 0, 14, skipped);  // a copy: nothing
  e = taken_entries(before, r);
  EXPECT_EQ(e.skipped + e.report + e.dropped, 0u);
}

TEST(MasterRecords, ARecordedAgentsIdIsNeverHandedOutAgain) {
  MasterConfig c;
  c.next_id = 2;
  c.records[7].first = 1;
  c.records[7].next = 4;
  c.records[7].reports = 3;
  Master<> m(c, 0);
  EXPECT_EQ(m.next_id(), 8u);
  EXPECT_EQ(m.report_records().at(7).stored(), 3u);
}

TEST(Record, LinesReadBackToTheSameRecord) {
  std::map<std::uint16_t, ReportRecord> mine;
  std::string text;
  const auto take = [&](std::uint16_t agent, std::uint32_t seq, std::uint32_t last, std::uint32_t first) {
    std::uint32_t skipped = 0;
    ReportRecord& r = mine[agent];
    const ReportRecord before = r;
    PCTake(r, seq, last, first, skipped);
    record_events(agent, taken_entries(before, r), MsgType::SENSOR_VALUE, "in4:US\t%\n",
                  [&](OperatorEvent&& e) { text += record_line(e); });
  };
  take(5, 1, 0, 1);
  take(5, 2, 4, 2);
  take(7, 3, 0, 3);
  take(7, 6, 0, 6);
  take(5, 5, 0, 5);
  EXPECT_NE(text.find("5\t1\t1\treport\tSENSOR_VALUE\tin4:US%09%25%0A\n"), std::string::npos) << text;
  std::map<std::uint16_t, ReportRecord> back;
  std::string why;
  std::size_t pos = 0;
  for (std::size_t nl; (nl = text.find('\n', pos)) != std::string::npos; pos = nl + 1)
    ASSERT_TRUE(apply_record_line(std::string_view(text).substr(pos, nl - pos), back, why)) << why;
  ASSERT_EQ(back.size(), 2u);
  for (const auto& kv : mine) {
    const ReportRecord& b = back[kv.first];
    EXPECT_EQ(b.first, kv.second.first);
    EXPECT_EQ(b.next, kv.second.next);
    EXPECT_EQ(b.reports, kv.second.reports);
    EXPECT_EQ(b.dropped, kv.second.dropped);
    EXPECT_EQ(b.skipped, kv.second.skipped);
  }
}

TEST(Record, ALineThatDoesNotFollowIsRefusedSayingWhy) {
  const std::pair<const char*, const char*> bad[] = {
      {"5\t1\t1\treport", "expected 6 tab-separated fields (agent first last kind type params), found 4"},
      {"1\t1\t1\treport\tACTION_OK\t0", "agent '1' is not an assigned id"},
      {"5\t0\t1\treport\tACTION_OK\t0", "are not numbers 1 <= first <= last"},
      {"5\t3\t2\tdropped\tREPORT_DROPPED\t", "are not numbers 1 <= first <= last"},
      {"5\t1\t2\treport\tACTION_OK\t0", "a report has one number"},
      {"5\t1\t1\tlost\tACTION_OK\t0", "kind 'lost' is not report, dropped or skipped"},
  };
  for (const auto& b : bad) {
    std::map<std::uint16_t, ReportRecord> r;
    std::string why;
    EXPECT_FALSE(apply_record_line(b.first, r, why)) << b.first;
    EXPECT_NE(why.find(b.second), std::string::npos) << why;
  }
  std::map<std::uint16_t, ReportRecord> r;
  std::string why;
  ASSERT_TRUE(apply_record_line("# a comment", r, why));
  ASSERT_TRUE(apply_record_line("5\t1\t1\treport\tACTION_OK\t0", r, why));
  ASSERT_TRUE(apply_record_line("7\t1\t4\tdropped\tREPORT_DROPPED", r, why)) << why;  // no empty params field
  EXPECT_EQ(r[7].dropped, 4u);
  EXPECT_FALSE(apply_record_line("5\t3\t3\treport\tACTION_OK\t0", r, why));
  EXPECT_EQ(why, "agent 5's entry starts at 3, expected 2");
}

TEST(AgentReports, AFullBufferDropsAndTheMarkerReachesTheMasterFirst) {
  AgentConfig c;
  c.timers = ev3test::fixed_timers();
  c.temp_id = 50001;
  Agent<NoTrace, 50, 8, 512, 16, kMaxDatagram, 4, 2, 1024> a(c, 0);  // 2 reports held at most
  a.handle_datagram("1:2:1:2:50001", 1, 0);  // MASTER: id 2
  Transmit t;
  while (a.poll_transmit(t)) {
  }
  for (int i = 0; i < 5; ++i) a.robot_event(RobotEventKind::OBSTACLE_DETECTED, "in1", 1);
  EXPECT_EQ(a.reports().made(), 5u);
  EXPECT_EQ(a.reports().dropped(), 3u);
  std::vector<std::string> out;
  while (a.poll_transmit(t)) out.emplace_back(t.bytes);
  ASSERT_EQ(out.size(), 5u);  // each sent once at once (no acknowledgement yet)
  out.clear();
  a.advance(1000);  // the heartbeat: PING, then the marker 1..3 and the report 4 (a window of 4)
  while (a.poll_transmit(t)) out.emplace_back(t.bytes);
  ASSERT_EQ(out.size(), 3u) << ::testing::PrintToString(out);
  EXPECT_EQ(out[1].substr(out[1].find(':', out[1].find(':', out[1].find(':') + 1) + 1) + 1), "41:1:3");
  EXPECT_NE(out[2].find(":40:4:1:"), std::string::npos) << out[2];
  a.handle_datagram("1:2:0:42:4", 1, 1001);  // the PC recorded the marker and 4: 5 goes now
  out.clear();
  while (a.poll_transmit(t)) out.emplace_back(t.bytes);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_NE(out[0].find(":40:5:5:"), std::string::npos) << out[0];
  EXPECT_EQ(a.reports().held(), 1u);
}

}  // namespace
