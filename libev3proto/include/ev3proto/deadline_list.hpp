/// @file deadline_list.hpp
/// @brief Deadlines that lie one fixed period after each key's last refresh, kept in refresh order:
///        the master's per-agent drop times (heard + drop) and resend times (sent_at + resend).
///
/// Both of the master's per-agent deadlines are a constant period after an event (the agent was
/// heard; the pending datagram was sent), and events come in time order. So the keys expire in the
/// order of their last refresh, and a list in that order is all the structure they need (a timing
/// wheel with a single slot per period): a refresh moves the key to the back, the front holds the
/// earliest deadline, and taking due keys takes them from the front. Every operation is O(1); no
/// search, no reordering, no walk of the keys (walking the registry for the earliest deadline after
/// every datagram would be most of the master's time at thousands of agents: docs/benchmarks.md,
/// "Master at scale").
/// The master runs on a PC: this allocates (a vector of links, indexed by key).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "timers.hpp"

namespace ev3proto {

/// Keys, each with a deadline `period` after the time it was last refreshed, in deadline order.
/// @tparam Key a small unsigned integer (the master: an agent id); its largest value is reserved.
template <typename Key>
class DeadlineList {
 public:
  /// "No deadline".
  static constexpr Millis kNever = ~Millis{0};

  /// An empty list whose deadlines lie @p period after each refresh.
  explicit DeadlineList(Millis period = 0) noexcept : period_(period) {}

  /// Key @p k was refreshed at @p at: its deadline is at + period. A key refreshed at the same time
  /// again keeps its place. Refreshes come in time order in the master (@p at is its clock), so the
  /// key goes to the back at once; an earlier @p at is placed by a scan from the back.
  void refresh(Key k, Millis at) {
    if (k >= links_.size()) links_.resize(static_cast<std::size_t>(k) + 1);
    Link& l = links_[k];
    if (l.listed && l.at == at) return;
    if (l.listed) unlink(k);
    l.at = at;
    l.listed = true;
    ++size_;
    Key after = tail_;  // the key to follow: the last one refreshed at or before at
    while (after != kNone && links_[after].at > at) after = links_[after].prev;
    l.prev = after;
    l.next = after == kNone ? head_ : links_[after].next;
    (l.prev == kNone ? head_ : links_[l.prev].next) = k;
    (l.next == kNone ? tail_ : links_[l.next].prev) = k;
  }

  /// Key @p k has no deadline any more.
  void remove(Key k) noexcept {
    if (k < links_.size() && links_[k].listed) unlink(k);
  }

  /// True when @p k has a deadline.
  bool contains(Key k) const noexcept { return k < links_.size() && links_[k].listed; }
  /// The deadline of @p k (kNever when it has none).
  Millis deadline(Key k) const noexcept { return contains(k) ? links_[k].at + period_ : kNever; }
  /// The earliest deadline (kNever when no key has one).
  Millis next() const noexcept { return head_ == kNone ? kNever : links_[head_].at + period_; }
  /// Keys with a deadline.
  std::size_t size() const noexcept { return size_; }

  /// Takes the key with the earliest deadline if it is due at @p now (deadline <= now); false when
  /// none is due.
  bool pop_due(Millis now, Key& out) noexcept {
    if (head_ == kNone || links_[head_].at + period_ > now) return false;
    out = head_;
    unlink(head_);
    return true;
  }

 private:
  static constexpr Key kNone = static_cast<Key>(~Key{0});
  struct Link {
    Millis at = 0;       // last refresh
    Key prev = kNone;    // refreshed before (kNone: the front)
    Key next = kNone;    // refreshed after (kNone: the back)
    bool listed = false; // has a deadline
  };

  void unlink(Key k) noexcept {
    Link& l = links_[k];
    (l.prev == kNone ? head_ : links_[l.prev].next) = l.next;
    (l.next == kNone ? tail_ : links_[l.next].prev) = l.prev;
    l.prev = l.next = kNone;
    l.listed = false;
    --size_;
  }

  Millis period_;
  std::vector<Link> links_;  // by key
  Key head_ = kNone, tail_ = kNone;
  std::size_t size_ = 0;
};

}  // namespace ev3proto
