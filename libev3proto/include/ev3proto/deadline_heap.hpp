/// @file deadline_heap.hpp
/// @brief One deadline per key for many keys (the master's per-agent resend and drop times): a
///        binary min-heap with lazy deletion, so that setting a key's deadline, taking a due key
///        and asking for the earliest deadline never walk all keys.
///
/// The master core (master.hpp) keeps one deadline per registry entry: the earlier of its drop time
/// (heard + drop) and, while a datagram is pending, its resend time (sent_at + resend). Every PING
/// moves an entry's drop time later; walking the registry for the earliest one after every datagram
/// cost the master most of its time at thousands of agents (issue 14). This structure allocates
/// (the master runs on a PC); the agent core does not include it.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "timers.hpp"

namespace ev3proto {

/// Deadlines by key: set(), clear(), next(), pop_due().
///
/// The heap holds (time, key) items. A key's *wanted* deadline lives beside it (a slot in a vector
/// indexed by the key); the heap item standing for the key (its *armed* item) is at that time or
/// earlier. Moving a deadline
/// later (an agent heard again) only updates the wanted time; the old item stays until it reaches
/// the top, where it is replaced by one at the wanted time. Moving a deadline earlier pushes a new
/// item, and the older one is skipped when it surfaces (lazy deletion). After every call the top
/// item is exact (its key wants exactly that time), so next() is the true earliest deadline.
///
/// Cost (n keys): set() and clear() O(log n) amortized, next() O(1), pop_due() O(log n) amortized.
/// Memory: one item per key plus one per deadline moved earlier and not yet surfaced, and a slot
/// for every key up to the largest one used.
/// @tparam Key a small unsigned integer (the master: an agent id; a load generator: an index).
template <typename Key>
class DeadlineHeap {
 public:
  /// "No deadline".
  static constexpr Millis kNever = ~Millis{0};

  /// Key @p k is due at @p when (earlier or later than before, or its first deadline).
  void set(Key k, Millis when) {
    if (k >= slots_.size()) slots_.resize(static_cast<std::size_t>(k) + 1);
    Slot& s = slots_[k];
    if (s.want == kNever) ++size_;
    s.want = when;
    if (s.seq == 0 || when < s.armed_at) push(k, when, s);
    settle();
  }

  /// Key @p k has no deadline any more.
  void clear(Key k) {
    forget(k);
    settle();
  }

  /// The earliest deadline (kNever when no key has one).
  Millis next() const noexcept { return heap_.empty() ? kNever : heap_.front().when; }

  /// Takes a key due at @p now (deadline <= now), earliest first, and clears its deadline; false
  /// when none is due.
  bool pop_due(Millis now, Key& out) {
    if (heap_.empty() || heap_.front().when > now) return false;
    out = heap_.front().key;
    pop();
    forget(out);
    settle();
    return true;
  }

  /// The deadline of @p k (kNever when it has none).
  Millis deadline(Key k) const noexcept { return k < slots_.size() ? slots_[k].want : kNever; }

  /// Keys with a deadline.
  std::size_t size() const noexcept { return size_; }
  /// Items in the heap (keys plus superseded items not surfaced yet): for tests and benchmarks.
  std::size_t heap_items() const noexcept { return heap_.size(); }

 private:
  struct Item {
    Millis when;
    Key key;
    std::uint64_t seq;  // which push made it: only the key's armed item counts
  };
  struct Slot {
    Millis want = kNever;     // the key's deadline (kNever: none)
    Millis armed_at = kNever; // the time of its armed item (<= want)
    std::uint64_t seq = 0;    // the armed item's seq (0: none)
  };
  /// Min-heap order for std::push_heap / std::pop_heap (which build max-heaps): later is "less".
  static bool later(const Item& a, const Item& b) noexcept { return a.when > b.when; }

  void push(Key k, Millis when, Slot& s) {
    s.armed_at = when;
    s.seq = ++seq_;
    heap_.push_back(Item{when, k, s.seq});
    std::push_heap(heap_.begin(), heap_.end(), later);
  }
  void pop() {
    std::pop_heap(heap_.begin(), heap_.end(), later);
    heap_.pop_back();
  }
  void forget(Key k) {
    if (k >= slots_.size() || slots_[k].want == kNever) return;
    slots_[k] = Slot{};  // its items in the heap no longer match a seq: skipped when they surface
    --size_;
  }

  /// Makes the top item exact: drops items of cleared keys and superseded items, and moves an
  /// armed item whose key now wants a later time to that time.
  void settle() {
    while (!heap_.empty()) {
      const Item top = heap_.front();
      Slot& s = slots_[top.key];
      if (s.seq != top.seq) {
        pop();  // cleared, or superseded by an earlier push
        continue;
      }
      if (s.want == top.when) return;
      pop();  // the key was moved later while this item waited
      push(top.key, s.want, s);
    }
  }

  std::vector<Item> heap_;
  std::vector<Slot> slots_;  // by key
  std::size_t size_ = 0;     // keys with a deadline
  std::uint64_t seq_ = 0;
};

}  // namespace ev3proto
