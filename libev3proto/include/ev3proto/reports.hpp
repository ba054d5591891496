/// @file reports.hpp
/// @brief Reliable reports, the home of spec/tla/Reports.tla: the agent's bounded buffer of
///        numbered reports (ReportBuffer: Make, Send's window, TakeAck) and a master's record of
///        each agent's reports (ReportRecord: PCTake, PCAck). No I/O; ReportBuffer allocates nothing.
///
/// An agent numbers its reports (SENSOR_VALUE, ACTION_OK / ACTION_INTERR / ACTION_ERR, EVENT) 1, 2,
/// 3, ... and keeps each, as the datagram it made, until the PC master (id 1) acknowledges it. A
/// report travels inside REPORT(seq, first, datagram), `first` being the lowest number the agent
/// still holds; a full buffer drops its oldest report into one drop marker (first..last), which
/// travels as REPORT_DROPPED(first, last). A master takes a number only as the next of that agent's
/// record and answers REPORT_ACK(stored), the last number of its record. Only the PC's
/// acknowledgement frees: an interim master (an agent elected while the PC is gone) takes and
/// acknowledges reports too, which stops the agent resending them to it, and the agent delivers
/// them to the PC when it follows the PC again. docs/reports.md explains the design and its bound.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "messages.hpp"

namespace ev3proto {

/// Numbers an agent has in flight to its master at once (sent, not acknowledged by it).
inline constexpr std::uint32_t kReportWindow = 4;
/// The agent's default bound: reports held at once, and their bytes (docs/reports.md: a
/// two-minute outage at the default reporting rate, with room to spare, in 72 KiB of the EV3's 64 MB).
inline constexpr std::size_t kReportSlots = 1024;
inline constexpr std::size_t kReportBytes = 64 * 1024;

/// The report types (SENSOR_VALUE, ACTION_OK / ACTION_INTERR / ACTION_ERR, EVENT).
constexpr bool is_report(MsgType t) noexcept {
  return t == MsgType::SENSOR_VALUE || t == MsgType::ACTION_OK || t == MsgType::ACTION_INTERR ||
         t == MsgType::ACTION_ERR || t == MsgType::EVENT;
}

/// The agent's reports not yet acknowledged by the PC (Reports.tla's made, lo, mk of one agent),
/// kept as the datagrams made, in a byte ring of @p Bytes holding at most @p Slots reports.
/// Numbers lo..mk (when mk >= lo) are the drop marker: their reports were dropped by the bound.
/// Numbers mk+1..made are held. Everything below lo is in the PC's record.
template <std::size_t Slots, std::size_t Bytes>
class ReportBuffer {
  static_assert(Slots >= 1 && Bytes >= 64 && Bytes <= 0xFFFFFFFFu, "a report buffer needs room");

 public:
  /// Reports held at most.
  static constexpr std::size_t kSlots = Slots;
  /// Longest report kept (a longer one is refused by Make).
  static constexpr std::size_t kMaxReport = Bytes / 4 < 65535 ? Bytes / 4 : 65535;

  /// Spec Make: the report @p datagram gets the next number; when that puts Slots + 1 reports
  /// in the buffer, or its bytes do not fit, the oldest are dropped into the marker. Returns the
  /// number, or 0 (nothing changed) when @p datagram is longer than kMaxReport.
  std::uint32_t Make(std::string_view datagram) noexcept {
    if (datagram.size() > kMaxReport || made_ == 0xFFFFFFFEu) return 0;
    std::uint32_t at = 0;
    while (held() >= limit_ || !place(datagram.size(), at)) drop_oldest();
    std::memcpy(bytes_ + at, datagram.data(), datagram.size());
    ++made_;
    Entry& e = ent_[made_ % Slots];
    e.off = at;
    e.len = static_cast<std::uint16_t>(datagram.size());
    tail_ = at + static_cast<std::uint32_t>(datagram.size());
    return made_;
  }

  /// Spec TakeAck: REPORT_ACK(@p n) from a master. From the PC (@p from_pc) it frees the numbers
  /// up to @p n; from the master the agent reports to (@p from_current) it stops their resending
  /// to it. An acknowledgement of a number never made is not ours: false, nothing changes.
  bool TakeAck(std::uint32_t n, bool from_pc, bool from_current) noexcept {
    if (n > made_) return false;
    if (from_current && n > cur_ack_) cur_ack_ = n;
    if (from_pc && n >= lo_) {
      lo_ = n + 1;
      if (mk_ < n) mk_ = n;  // the held reports up to n are freed
      if (held() == 0) tail_ = 0;
      if (cur_ack_ < n) cur_ack_ = n;
    }
    if (sent_ < cur_ack_) sent_ = cur_ack_;
    return true;
  }

  /// Holds at most @p n reports (1..Slots; 0 or more than Slots: Slots), a bound set at run time
  /// below the compiled one (ev3-agent --report-buffer). Set it while nothing is held.
  void set_limit(std::size_t n) noexcept {
    limit_ = n == 0 || n > Slots ? static_cast<std::uint32_t>(Slots) : static_cast<std::uint32_t>(n);
  }

  /// The agent reports to another master from now on (synced anew, a relay, an election): it has
  /// acknowledged nothing yet, so everything held is sent to it.
  void new_master() noexcept { cur_ack_ = sent_ = lo_ - 1; }

  /// Report @p seq, just made, went to the current master at once (its first sending, outside
  /// the window): when everything before it had gone too, the window moves past it.
  void sent_at_once(std::uint32_t seq) noexcept {
    if (sent_ + 1 == seq) sent_ = seq;
  }

  /// A round of retries (the heartbeat): what the current master has not acknowledged is sent
  /// again from its start.
  void retry() noexcept { sent_ = cur_ack_; }

  /// One datagram of Send's window: the next number to send to the current master, when the
  /// window has room. @p marker is set for the drop marker (REPORT_DROPPED(lo(), mk())), else
  /// @p seq and @p datagram are the report's. The caller sends it and calls sent(). False when
  /// there is nothing to send or the window is full.
  bool next(bool& marker, std::uint32_t& seq, std::string_view& datagram) const noexcept {
    if (sent_ >= made_ || sent_ - cur_ack_ >= kReportWindow) return false;  // sent_ >= cur_ack_ always
    const std::uint32_t s = sent_ + 1;
    marker = s <= mk_;
    seq = marker ? mk_ : s;
    if (!marker) {
      const Entry& e = ent_[s % Slots];
      datagram = std::string_view(bytes_ + e.off, e.len);
    }
    return true;
  }
  /// next()'s datagram went out: @p seq (the marker's last number for a marker) is in flight.
  void sent(std::uint32_t seq) noexcept {
    if (seq > sent_) sent_ = seq;
  }

  /// Reports made (the last number given).
  std::uint32_t made() const noexcept { return made_; }
  /// The lowest number held (as a report or in the marker); made() + 1 when none is.
  std::uint32_t lo() const noexcept { return lo_; }
  /// The marker's last number (the marker is lo()..mk() when mk() >= lo()).
  std::uint32_t mk() const noexcept { return mk_; }
  /// Reports held (not dropped, not freed).
  std::uint32_t held() const noexcept { return made_ - mk_; }
  /// Reports the bound dropped, in all.
  std::uint32_t dropped() const noexcept { return dropped_; }
  /// The highest number the current master acknowledged.
  std::uint32_t current_ack() const noexcept { return cur_ack_; }

 private:
  struct Entry {
    std::uint32_t off = 0;
    std::uint16_t len = 0;
  };

  /// Where @p len bytes go after the newest report: at tail_ or, wrapping, at 0. False when they
  /// would overwrite a held report.
  bool place(std::size_t len, std::uint32_t& at) noexcept {
    if (held() == 0) {
      at = 0;
      return len <= Bytes;
    }
    const std::uint32_t head = ent_[(mk_ + 1) % Slots].off;
    if (tail_ > head) {  // held bytes are head..tail_: free at the end, then before head
      if (len <= Bytes - tail_) {
        at = tail_;
        return true;
      }
      at = 0;
      return len <= head;
    }
    at = tail_;  // held bytes wrap: free is tail_..head
    return len <= head - tail_;
  }

  void drop_oldest() noexcept {
    ++mk_;
    ++dropped_;
    if (held() == 0) tail_ = 0;
  }

  std::uint32_t made_ = 0, lo_ = 1, mk_ = 0;
  std::uint32_t cur_ack_ = 0, sent_ = 0;  // the current master: acknowledged, sent
  std::uint32_t dropped_ = 0;
  std::uint32_t tail_ = 0;                // the byte after the newest report
  std::uint32_t limit_ = static_cast<std::uint32_t>(Slots);  // reports held at most (set_limit)
  Entry ent_[Slots];
  char bytes_[Bytes];
};

/// What a master holds of one agent's reports (Reports.tla's rec and nx of one agent, kept as
/// counts; the reports themselves go to the operator and, on the PC, to the program's record).
struct ReportRecord {
  std::uint32_t first = 0;    ///< The first number recorded (0: nothing yet).
  std::uint32_t next = 0;     ///< The number taken next (spec nx; 0: nothing recorded yet).
  std::uint32_t reports = 0;  ///< Numbers recorded as reports.
  std::uint32_t dropped = 0;  ///< Numbers recorded as dropped by the agent's bound.
  std::uint32_t skipped = 0;  ///< Numbers the agent no longer held when offered to this master.
  std::uint32_t ahead = 0;    ///< Highest number offered beyond next (a gap its retries fill; 0: none).
  /// The last number recorded (the acknowledgement REPORT_ACK carries).
  std::uint32_t stored() const noexcept { return next == 0 ? 0 : next - 1; }
};

/// What PCTake did with an offered number.
enum class ReportTaken : std::uint8_t {
  stored,   ///< the report was the next: recorded
  dropped,  ///< the marker covered the next: its numbers up to its last recorded as dropped
  copy,     ///< already recorded (a copy, a retry): nothing recorded, acknowledged again
  ahead,    ///< beyond the next (one before it was lost): left for the retries
  invalid,  ///< not a valid offer (number 0, first above the number, a marker upside down)
};

/// Spec PCTake on record @p r: number @p seq (a report when @p last == 0, else the marker
/// @p seq..@p last) offered with @p first, the lowest the agent holds. A record with nothing yet
/// starts at @p first; numbers below @p first that it lacks are recorded as skipped (@p skipped
/// set to how many, else 0). Then PCAck acknowledges r.stored().
inline ReportTaken PCTake(ReportRecord& r, std::uint32_t seq, std::uint32_t last, std::uint32_t first,
                          std::uint32_t& skipped) noexcept {
  skipped = 0;
  const bool marker = last != 0;
  if (seq == 0 || first == 0 || first > seq || (marker && (last < seq || first != seq))) return ReportTaken::invalid;
  if (r.next == 0) r.first = r.next = first;
  if (first > r.next) {
    skipped = first - r.next;
    r.skipped += skipped;
    r.next = first;
  }
  ReportTaken t = ReportTaken::copy;
  if (marker) {
    if (seq <= r.next && r.next <= last) {
      r.dropped += last - r.next + 1;
      r.next = last + 1;
      t = ReportTaken::dropped;
    } else if (seq > r.next) {
      t = ReportTaken::ahead;
    }
  } else if (seq == r.next) {
    ++r.reports;
    ++r.next;
    t = ReportTaken::stored;
  } else if (seq > r.next) {
    t = ReportTaken::ahead;
  }
  const std::uint32_t top = marker ? last : seq;
  if (t == ReportTaken::ahead && top > r.ahead) r.ahead = top;
  if (r.ahead <= r.next) r.ahead = 0;  // every number below the highest seen is recorded
  return t;
}

/// What one PCTake added to a record, in the order its numbers were recorded: @c skipped numbers
/// from @c skipped_from, then the report numbered @c report (0: none), then @c dropped numbers from
/// @c dropped_from. The record's entries (record.hpp, OperatorEvent::recorded) are these.
struct ReportEntries {
  std::uint32_t skipped_from = 0, skipped = 0;
  std::uint32_t report = 0;
  std::uint32_t dropped_from = 0, dropped = 0;
};

/// The entries PCTake made on a record that was @p before and is @p after.
inline ReportEntries taken_entries(const ReportRecord& before, const ReportRecord& after) noexcept {
  ReportEntries e;
  std::uint32_t next = before.next == 0 ? after.first : before.next;
  e.skipped_from = next;
  e.skipped = after.skipped - before.skipped;
  next += e.skipped;
  if (after.reports != before.reports) e.report = next++;
  e.dropped_from = next;
  e.dropped = after.dropped - before.dropped;
  return e;
}

}  // namespace ev3proto
