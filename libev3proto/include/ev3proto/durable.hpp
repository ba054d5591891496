/// @file durable.hpp
/// @brief The durable state as a file keeps it: text and validation, one rule for every program.
///
/// The durable state is what a node must find again after a restart (an SD card, a disk): the
/// agent's Durable (election/common.hpp: epoch, vote, the membership it knows and its floor) and the
/// master's MasterDurable (next id, next msgid, epoch, the membership it published). Both are
/// `key=value` lines, one key a line, in any order; a line without '=' or starting with '#' is
/// skipped, a key given twice counts with its last value, an unknown key is ignored:
///
///     epoch=5             next_id=12
///     voted_for=7         next_msgid=1048576
///     members=7,8,9       epoch=5
///     members_epoch=4     members=7,8,9
///     floor=5             members_epoch=4
///
/// The membership rule, shared by both: `members` lists at most kMaxMembership distinct agent ids
/// 2..49999, comma-separated ("" or no key: none); `members_epoch` (no key: 0) is the epoch that
/// published the list, at most `epoch`, and at least 1 when the list names agents. The agent's
/// `floor` (no key: 0) lies between `members_epoch` and `epoch`: learning a membership raises the
/// floor to its epoch. A refusal names the key and says why ("members_epoch: 7 is above epoch 5").
///
/// Header-only, no I/O, no heap, no exceptions: the program writes the text atomically (a temporary
/// file, fsync, rename) and hands the text it reads to parse_durable / parse_master_durable.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core.hpp"
#include "decimal.hpp"
#include "election/common.hpp"
#include "wire.hpp"

namespace ev3proto {

/// Text of bounded size in a fixed buffer (a state file's text, a refusal, an id list).
template <std::size_t N>
class FixedText {
 public:
  /// The text so far.
  std::string_view view() const noexcept { return {buf_, n_}; }
  /// Appends @p s, cut at the capacity.
  FixedText& put(std::string_view s) noexcept {
    for (char c : s)
      if (n_ < N) buf_[n_++] = c;
    return *this;
  }
  /// Appends @p v in decimal.
  FixedText& num(std::uint32_t v) noexcept {
    char d[10];
    return put(decimal(v, d));
  }
  /// Appends "'s'", @p s cut to 40 characters and "..." when longer.
  FixedText& quoted(std::string_view s) noexcept {
    put("'");
    put(s.substr(0, 40));
    return put(s.size() > 40 ? "...'" : "'");
  }
  /// Appends ids @p ids[0..n) comma-separated ("" for none).
  FixedText& ids(const std::uint16_t* ids, std::size_t n) noexcept {
    for (std::size_t i = 0; i < n; ++i) (i ? put(",") : *this).num(ids[i]);
    return *this;
  }
  /// Empties it.
  void clear() noexcept { n_ = 0; }

 private:
  char buf_[N] = {};
  std::size_t n_ = 0;
};

/// Why a stored state was refused ("members_epoch: 7 is above epoch 5"); empty when accepted.
using DurableError = FixedText<192>;
/// A state file's text: room for every key at its longest.
using DurableText = FixedText<320>;
/// A membership as text ("7,8,9").
using IdListText = FixedText<kMaxMembership * 6>;

/// What ev3-master keeps on stable storage: enough to restart as a candidate of the fleet it ran.
struct MasterDurable {
  std::uint16_t next_id = kFirstAssignedId; ///< `next_id`: the next agent id to assign (2..65535).
  std::uint32_t next_msgid = 1;             ///< `next_msgid`: the first msgid to send after a restart (>= 1).
  std::uint32_t epoch = 1;                  ///< `epoch`: the master's epoch (>= 1).
  std::uint32_t members_epoch = 0;          ///< `members_epoch`: epoch that published the list (0: none).
  std::uint8_t member_count = 0;            ///< Members in use.
  std::uint16_t members[kMaxMembership] = {}; ///< `members`: the membership it published.
};

namespace detail {

/// The value of the last line "key=..." of @p text; false when there is none.
constexpr bool durable_value(std::string_view text, std::string_view key, std::string_view& out) noexcept {
  bool found = false;
  for (std::size_t pos = 0; pos < text.size();) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view line = text.substr(pos, end - pos);
    const std::size_t eq = line.find('=');
    if (eq != std::string_view::npos && line[0] != '#' && line.substr(0, eq) == key) {
      out = line.substr(eq + 1);
      found = true;
    }
    pos = end + 1;
  }
  return found;
}

/// A canonical decimal number ("0", or a non-zero digit and more digits) of at most 2^32 - 1.
constexpr bool durable_number(std::string_view s, std::uint32_t& out) noexcept {
  if (s.empty() || s.size() > 10 || (s.size() > 1 && s[0] == '0')) return false;
  std::uint64_t v = 0;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + static_cast<std::uint64_t>(c - '0');
  }
  if (v > 0xFFFFFFFFu) return false;
  out = static_cast<std::uint32_t>(v);
  return true;
}

/// Key @p key of @p text as a number lo..hi into @p out: @p dflt when absent or empty if
/// @p optional, else refused ("epoch: missing", "voted_for: 'x' is not a number 0..65535").
inline bool durable_field(std::string_view text, std::string_view key, bool optional, std::uint32_t dflt,
                          std::uint32_t lo, std::uint32_t hi, std::uint32_t& out, DurableError& err) noexcept {
  std::string_view v;
  if (!durable_value(text, key, v) || v.empty()) {
    out = dflt;
    if (optional) return true;
    err.put(key).put(": missing");
    return false;
  }
  if (durable_number(v, out) && out >= lo && out <= hi) return true;
  err.put(key).put(": ").quoted(v).put(" is not a number ").num(lo).put("..").num(hi);
  return false;
}

/// The optional keys of the membership (members, members_epoch) into @p ids / @p count / @p mepoch
/// (@p given: members_epoch has a value): the syntax only (check_membership judges the values).
inline bool parse_members(std::string_view text, std::uint16_t* ids, std::uint8_t& count, std::uint32_t& mepoch,
                          bool& given, DurableError& err) noexcept {
  count = 0;
  std::string_view list;
  durable_value(text, "members", list);
  for (std::size_t pos = 0; !list.empty() && pos <= list.size();) {
    std::size_t comma = list.find(',', pos);
    if (comma == std::string_view::npos) comma = list.size();
    std::uint32_t id = 0;
    if (count == kMaxMembership || !durable_number(list.substr(pos, comma - pos), id) || id > 0xFFFFu) {
      count = 0;
      err.put("members: ").quoted(list).put(" is not a list of at most ").num(static_cast<std::uint32_t>(kMaxMembership)).put(
          " agent ids, comma-separated");
      return false;
    }
    ids[count++] = static_cast<std::uint16_t>(id);
    pos = comma + 1;
  }
  std::string_view v;
  mepoch = 0;
  given = durable_value(text, "members_epoch", v) && !v.empty();
  if (given && !durable_number(v, mepoch)) {
    err.put("members_epoch: ").quoted(v).put(" is not a number");
    return false;
  }
  return true;
}

/// @p d into @p out when @p ok (the state passed the rule); @p ok.
template <typename T>
bool accepted(bool ok, const T& d, T& out) noexcept {
  if (ok) out = d;
  return ok;
}

}  // namespace detail

/// The membership rule: @p ids[0..count) are at most kMaxMembership distinct agent ids 2..49999,
/// published in epoch @p mepoch, which is at most @p epoch and at least 1 when there are ids.
/// @p mepoch_given: false when the state had no members_epoch (said so in the refusal).
inline bool check_membership(const std::uint16_t* ids, std::size_t count, std::uint32_t mepoch, std::uint32_t epoch,
                             DurableError& err, bool mepoch_given = true) noexcept {
  if (count > kMaxMembership) {
    err.put("members: ").num(static_cast<std::uint32_t>(count)).put(" ids, more than ").num(static_cast<std::uint32_t>(kMaxMembership));
    return false;
  }
  for (std::size_t i = 0; i < count; ++i) {
    if (!is_assigned_id(ids[i])) {
      err.put("members: ").num(ids[i]).put(" is not an agent id ").num(kFirstAssignedId).put("..").num(kLastAssignedId);
      return false;
    }
    for (std::size_t j = 0; j < i; ++j)
      if (ids[j] == ids[i]) {
        err.put("members: ").num(ids[i]).put(" is listed twice");
        return false;
      }
  }
  if (mepoch > epoch) {
    err.put("members_epoch: ").num(mepoch).put(" is above epoch ").num(epoch);
    return false;
  }
  if (count > 0 && mepoch == 0) {
    err.put(mepoch_given ? "members_epoch: 0" : "members_epoch: missing")
        .put(", but members lists agents (the epoch that published them is needed)");
    return false;
  }
  return true;
}

/// The agent's durable state by the rule: epoch >= 1, the membership rule, and
/// members_epoch <= floor <= epoch. False with the key named in @p err.
inline bool check_durable(const Durable& d, DurableError& err, bool mepoch_given = true) noexcept {
  if (d.epoch == 0) {
    err.put("epoch: 0 is not a number 1..4294967295");
    return false;
  }
  if (!check_membership(d.members, d.member_count, d.mepoch, d.epoch, err, mepoch_given)) return false;
  if (d.floor > d.epoch) {
    err.put("floor: ").num(d.floor).put(" is above epoch ").num(d.epoch);
    return false;
  }
  if (d.floor < d.mepoch) {
    err.put("floor: ").num(d.floor).put(" is below members_epoch ").num(d.mepoch).put(
        " (learning a membership raises the floor to its epoch)");
    return false;
  }
  return true;
}

/// The master's durable state by the rule: next_id >= 2, next_msgid >= 1, epoch >= 1 and the
/// membership rule. False with the key named in @p err.
inline bool check_master_durable(const MasterDurable& d, DurableError& err, bool mepoch_given = true) noexcept {
  if (d.next_id < kFirstAssignedId) {
    err.put("next_id: ").num(d.next_id).put(" is not a number ").num(kFirstAssignedId).put("..65535");
    return false;
  }
  if (d.next_msgid == 0 || d.epoch == 0) {
    err.put(d.epoch == 0 ? "epoch" : "next_msgid").put(": 0 is not a number 1..4294967295");
    return false;
  }
  return check_membership(d.members, d.member_count, d.members_epoch, d.epoch, err, mepoch_given);
}

/// The agent's state file text of @p d: epoch, voted_for, members, members_epoch, floor.
inline DurableText durable_text(const Durable& d) noexcept {
  DurableText t;
  t.put("epoch=").num(d.epoch).put("\nvoted_for=").num(d.voted_for).put("\nmembers=").ids(d.members, d.member_count);
  t.put("\nmembers_epoch=").num(d.mepoch).put("\nfloor=").num(d.floor).put("\n");
  return t;
}

/// The master's state file text of @p d: next_id, next_msgid, epoch, members, members_epoch.
inline DurableText durable_text(const MasterDurable& d) noexcept {
  DurableText t;
  t.put("next_id=").num(d.next_id).put("\nnext_msgid=").num(d.next_msgid).put("\nepoch=").num(d.epoch);
  t.put("\nmembers=").ids(d.members, d.member_count).put("\nmembers_epoch=").num(d.members_epoch).put("\n");
  return t;
}

/// Reads the agent's state file text @p text into @p out and checks it (check_durable). `epoch`
/// and `voted_for` are required; members, members_epoch, floor may be absent (a state that knows no
/// membership). False with the key named in @p err; @p out is then the defaults.
inline bool parse_durable(std::string_view text, Durable& out, DurableError& err) noexcept {
  out = Durable{};
  err.clear();
  Durable d;
  std::uint32_t voted = 0;
  bool given = false;
  const bool ok = detail::durable_field(text, "epoch", false, 1, 1, 0xFFFFFFFFu, d.epoch, err) &&
                  detail::durable_field(text, "voted_for", false, 0, 0, 0xFFFFu, voted, err) &&
                  detail::parse_members(text, d.members, d.member_count, d.mepoch, given, err) &&
                  detail::durable_field(text, "floor", true, 0, 0, 0xFFFFFFFFu, d.floor, err);
  d.voted_for = static_cast<std::uint16_t>(voted);
  return detail::accepted(ok && check_durable(d, err, given), d, out);
}

/// Reads the master's state file text @p text into @p out and checks it (check_master_durable).
/// `next_id`, `next_msgid` and `epoch` are required; members and members_epoch may be absent. False
/// with the key named in @p err; @p out is then the defaults.
inline bool parse_master_durable(std::string_view text, MasterDurable& out, DurableError& err) noexcept {
  out = MasterDurable{};
  err.clear();
  MasterDurable d;
  std::uint32_t id = 0;
  bool given = false;
  const bool ok = detail::durable_field(text, "next_id", false, 0, kFirstAssignedId, 0xFFFFu, id, err) &&
                  detail::durable_field(text, "next_msgid", false, 1, 1, 0xFFFFFFFFu, d.next_msgid, err) &&
                  detail::durable_field(text, "epoch", false, 1, 1, 0xFFFFFFFFu, d.epoch, err) &&
                  detail::parse_members(text, d.members, d.member_count, d.members_epoch, given, err);
  d.next_id = static_cast<std::uint16_t>(id);
  return detail::accepted(ok && check_master_durable(d, err, given), d, out);
}

}  // namespace ev3proto
