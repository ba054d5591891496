/// @file record.hpp
/// @brief The PC master's record of reports as a file keeps it (`ev3-master --record FILE`): one
///        line per entry, and the rule a restarted master reads it back by. Master side: may allocate.
///
/// Every entry of the record (OperatorEvent::recorded: a numbered report, a drop, a skip) is one
/// line of six tab-separated fields (the last, params, empty but for a report), appended in the
/// order recorded:
///
///     agent   first   last   kind      type           params
///     5       17      17     report    SENSOR_VALUE   in4:US-DIST-CM:255
///     5       18      40     dropped   REPORT_DROPPED
///     7       1       3      skipped   REPORT
///
/// `params` are the report's params joined by ':' as the console shows them, with '%', tab, CR,
/// LF and bytes outside 0x20..0x7E written %XX; read back, a line may leave out an empty params
/// field and its tab. Lines starting with '#' are comments. Read back,
/// each agent's entries must follow each other (first = the previous last + 1): a line that does
/// not is refused, naming its line number and what it expected.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <string_view>

#include "master_types.hpp"
#include "reports.hpp"

namespace ev3proto {

/// The header line a new record file starts with.
inline constexpr std::string_view kRecordHeader = "# ev3-master record of reports: agent first last kind type params";

/// The line (with its newline) for entry @p e of the record; "" for an event that is not one.
inline std::string record_line(const OperatorEvent& e) {
  if (!e.recorded()) return {};
  const bool report = e.kind == OperatorEvent::Kind::report;
  std::string s = std::to_string(e.agent) + '\t' + std::to_string(e.seq) + '\t' +
                  std::to_string(report ? e.seq : e.last) + '\t' +
                  (report ? "report" : e.kind == OperatorEvent::Kind::reports_dropped ? "dropped" : "skipped") + '\t' +
                  std::string(to_string(e.command)) + '\t';
  static const char kHex[] = "0123456789ABCDEF";
  for (const char ch : e.text) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '%' || c < 0x20 || c > 0x7E) {
      s += '%';
      s += kHex[c >> 4];
      s += kHex[c & 15];
    } else {
      s += ch;
    }
  }
  return s + '\n';
}

/// The entries @p e that PCTake made on @p agent's record (taken_entries), as the operator events
/// the master reports them by, each handed to @p emit: the skipped numbers, the report (of type
/// @p type, its params @p text joined by ':'), the numbers recorded as dropped.
template <typename Emit>
void record_events(std::uint16_t agent, const ReportEntries& e, MsgType type, std::string_view text, Emit&& emit) {
  const auto event = [&](OperatorEvent::Kind k, MsgType t, std::uint32_t seq, std::uint32_t last, std::string_view s) {
    OperatorEvent ev;
    ev.kind = k;
    ev.agent = agent;
    ev.command = t;
    ev.text = std::string(s);
    ev.seq = seq;
    ev.last = last;
    emit(std::move(ev));
  };
  if (e.skipped != 0)
    event(OperatorEvent::Kind::reports_skipped, MsgType::REPORT, e.skipped_from, e.skipped_from + e.skipped - 1, {});
  if (e.report != 0) event(OperatorEvent::Kind::report, type, e.report, 0, text);
  if (e.dropped != 0)
    event(OperatorEvent::Kind::reports_dropped, MsgType::REPORT_DROPPED, e.dropped_from, e.dropped_from + e.dropped - 1, {});
}

namespace detail {
/// A canonical decimal number of at most 10 digits, at most @p max.
inline bool record_number(std::string_view f, std::uint32_t max, std::uint32_t& out) {
  if (f.empty() || f.size() > 10 || (f.size() > 1 && f[0] == '0')) return false;
  std::uint64_t v = 0;
  for (char c : f) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + static_cast<std::uint64_t>(c - '0');
  }
  if (v > max) return false;
  out = static_cast<std::uint32_t>(v);
  return true;
}
}  // namespace detail

/// Applies the record's line @p line (without its newline) to @p records, as the master recorded
/// it. False, with @p why saying what is wrong, when it is not a valid entry that follows the
/// agent's previous one; comments and empty lines change nothing.
inline bool apply_record_line(std::string_view line, std::map<std::uint16_t, ReportRecord>& records, std::string& why) {
  if (line.empty() || line[0] == '#') return true;
  std::string_view f[6];
  std::size_t n = 0;
  for (std::size_t pos = 0; n < 6;) {
    const std::size_t tab = n < 5 ? line.find('\t', pos) : std::string_view::npos;
    f[n++] = line.substr(pos, tab == std::string_view::npos ? std::string_view::npos : tab - pos);
    if (tab == std::string_view::npos) break;
    pos = tab + 1;
  }
  if (n != 6 && n != 5) {
    why = "expected 6 tab-separated fields (agent first last kind type params), found " + std::to_string(n);
    return false;
  }
  std::uint32_t agent = 0, first = 0, last = 0;
  if (!detail::record_number(f[0], 0xFFFF, agent) || !is_assigned_id(static_cast<std::uint16_t>(agent))) {
    why = "agent '" + std::string(f[0].substr(0, 12)) + "' is not an assigned id (2..49999)";
    return false;
  }
  if (!detail::record_number(f[1], 0xFFFFFFFFu, first) || first == 0 || !detail::record_number(f[2], 0xFFFFFFFFu, last) ||
      last < first || last == 0xFFFFFFFFu) {
    why = "first '" + std::string(f[1].substr(0, 12)) + "' and last '" + std::string(f[2].substr(0, 12)) +
          "' are not numbers 1 <= first <= last";
    return false;
  }
  const std::string_view kind = f[3];
  if (kind != "report" && kind != "dropped" && kind != "skipped") {
    why = "kind '" + std::string(kind.substr(0, 12)) + "' is not report, dropped or skipped";
    return false;
  }
  if (kind == "report" && first != last) {
    why = "a report has one number (first " + std::to_string(first) + ", last " + std::to_string(last) + ")";
    return false;
  }
  ReportRecord& r = records[static_cast<std::uint16_t>(agent)];
  if (r.next == 0) r.first = r.next = first;
  if (first != r.next) {
    why = "agent " + std::to_string(agent) + "'s entry starts at " + std::to_string(first) + ", expected " +
          std::to_string(r.next);
    return false;
  }
  const std::uint32_t count = last - first + 1;
  if (kind == "report") r.reports += count;
  if (kind == "dropped") r.dropped += count;
  if (kind == "skipped") r.skipped += count;
  r.next = last + 1;
  return true;
}

}  // namespace ev3proto
