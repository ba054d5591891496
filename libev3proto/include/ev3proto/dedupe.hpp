/// @file dedupe.hpp
/// @brief Duplicate detection keyed by (sender, msgid) with first-in-first-out eviction.
///
/// Every datagram is sent three times and a command may be resent with the same msgid; the receiver
/// acts on a (sender, msgid) once and answers repeats with the answer it recorded the first time
/// (docs/protocol.md, "Duplicates"). Keys are exact pairs, so msgid wrap-around needs no special case.
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>

namespace ev3proto {

/// Payload type for a DedupeWindow that only needs to know "seen before or not".
struct NoPayload {};

/// A window of the last @p Capacity distinct (sender, msgid) keys, each with a payload @p V (or of
/// fewer: set_limit(), for one compiled size that serves every window the spec is checked with).
///
/// Storage is inline (no heap): a ring of the keys in insertion order and an open-addressing index
/// (linear probing, a power of two >= 2 * Capacity slots, backward-shift deletion). find() and
/// insert() are O(1) on average; inserting into a full window evicts the oldest key.
/// @tparam Capacity number of keys remembered (>= 1).
/// @tparam V payload stored with each key; must be default-constructible and copy-assignable.
template <std::size_t Capacity = 50, typename V = NoPayload>
class DedupeWindow {
  static_assert(Capacity >= 1, "DedupeWindow needs room for at least one key");
  static_assert(Capacity <= 0x7FFFFFFFu, "DedupeWindow capacity too large");
  static_assert(std::is_default_constructible<V>::value, "payload must be default-constructible");

 public:
  /// Slot type of the index: the smallest unsigned type that holds Capacity plus an "empty" marker.
  using Slot = std::conditional_t<(Capacity < 0xFFFFu), std::uint16_t, std::uint32_t>;

  /// Number of slots of the index: the smallest power of two >= 2 * Capacity.
  static constexpr std::size_t kIndexSize = [] {
    std::size_t n = 1;
    while (n < 2 * Capacity) n *= 2;
    return n;
  }();

  /// An empty window.
  DedupeWindow() noexcept { clear(); }

  /// Holds at most @p n keys from now on (1..Capacity; 0 or more than Capacity: Capacity) and
  /// forgets every key.
  void set_limit(std::size_t n) noexcept {
    limit_ = n == 0 || n > Capacity ? Capacity : n;
    clear();
  }

  /// Most keys held at once (set_limit(); Capacity unless limited).
  std::size_t limit() const noexcept { return limit_; }

  /// Forgets every key.
  void clear() noexcept {
    for (std::size_t i = 0; i < kIndexSize; ++i) index_[i] = kEmpty;
    size_ = 0;
    head_ = 0;
  }

  /// Number of keys held (at most limit()).
  std::size_t size() const noexcept { return size_; }

  /// Most keys held at once.
  static constexpr std::size_t capacity() noexcept { return Capacity; }

  /// True if (sender, msgid) is in the window.
  bool contains(std::uint16_t sender, std::uint32_t msgid) const noexcept {
    return find(sender, msgid) != nullptr;
  }

  /// The payload recorded for (sender, msgid), or nullptr if the key is not in the window.
  const V* find(std::uint16_t sender, std::uint32_t msgid) const noexcept {
    const std::size_t pos = locate(make_key(sender, msgid));
    return index_[pos] == kEmpty ? nullptr : &values_[index_[pos]];
  }

  /// The payload recorded for (sender, msgid), or nullptr; mutable access.
  V* find(std::uint16_t sender, std::uint32_t msgid) noexcept {
    const std::size_t pos = locate(make_key(sender, msgid));
    return index_[pos] == kEmpty ? nullptr : &values_[index_[pos]];
  }

  /// Records (sender, msgid) with @p value. A key already present keeps its place in the FIFO order
  /// and gets the new value; returns false then. Otherwise the key becomes the newest, evicting the
  /// oldest key if the window is full (limit() keys), and true is returned.
  bool insert(std::uint16_t sender, std::uint32_t msgid, const V& value) noexcept(
      std::is_nothrow_copy_assignable<V>::value) {
    const std::uint64_t key = make_key(sender, msgid);
    std::size_t pos = locate(key);
    if (index_[pos] != kEmpty) {
      values_[index_[pos]] = value;
      return false;
    }
    std::size_t ring_slot;
    if (size_ == limit_) {
      ring_slot = head_;  // the oldest key
      erase_index(locate(keys_[ring_slot]));
      pos = locate(key);  // deletion may have moved entries
      head_ = head_ + 1 == limit_ ? 0 : head_ + 1;
    } else {
      ring_slot = head_ + size_;
      if (ring_slot >= limit_) ring_slot -= limit_;
      ++size_;
    }
    keys_[ring_slot] = key;
    values_[ring_slot] = value;
    index_[pos] = static_cast<Slot>(ring_slot);
    return true;
  }

  /// Calls @p f(sender, msgid, payload) for every key held, oldest first (read-only; for traces).
  template <typename F>
  void for_each(F&& f) const {
    for (std::size_t k = 0; k < size_; ++k) {
      std::size_t slot = head_ + k;
      if (slot >= limit_) slot -= limit_;
      f(static_cast<std::uint16_t>(keys_[slot] >> 32), static_cast<std::uint32_t>(keys_[slot]),
        values_[slot]);
    }
  }

  /// Records (sender, msgid) with a default payload if it is new. Returns true if it was new (act on
  /// the message), false if it is a repeat (do not act again).
  bool first_time(std::uint16_t sender, std::uint32_t msgid) noexcept(
      std::is_nothrow_copy_assignable<V>::value) {
    if (find(sender, msgid) != nullptr) return false;
    return insert(sender, msgid, V{});
  }

 private:
  static constexpr Slot kEmpty = static_cast<Slot>(~Slot{0});
  static constexpr std::size_t kMask = kIndexSize - 1;

  static constexpr std::uint64_t make_key(std::uint16_t sender, std::uint32_t msgid) noexcept {
    return (std::uint64_t{sender} << 32) | msgid;
  }

  /// Home slot of a key: a 32-bit multiplicative mix (cheap on the 32-bit EV3).
  static constexpr std::size_t home(std::uint64_t key) noexcept {
    const std::uint32_t lo = static_cast<std::uint32_t>(key);
    const std::uint32_t hi = static_cast<std::uint32_t>(key >> 32);
    std::uint32_t h = lo * 0x9E3779B1u ^ hi * 0x85EBCA77u;
    h ^= h >> 15;
    h *= 0x2C1B3C6Du;
    h ^= h >> 13;
    return static_cast<std::size_t>(h) & kMask;
  }

  /// The index slot holding @p key, or the empty slot where it would go.
  std::size_t locate(std::uint64_t key) const noexcept {
    std::size_t pos = home(key);
    while (index_[pos] != kEmpty && keys_[index_[pos]] != key) pos = (pos + 1) & kMask;
    return pos;
  }

  /// Empties index slot @p hole and shifts later entries of the probe run back so that every
  /// remaining key stays reachable from its home slot (no tombstones).
  void erase_index(std::size_t hole) noexcept {
    std::size_t j = hole;
    for (;;) {
      j = (j + 1) & kMask;
      if (index_[j] == kEmpty) break;
      const std::size_t h = home(keys_[index_[j]]);
      // Move the entry at j into the hole unless its home lies cyclically in (hole, j].
      const std::size_t dist_home = (j - h) & kMask;
      const std::size_t dist_hole = (j - hole) & kMask;
      if (dist_home >= dist_hole) {
        index_[hole] = index_[j];
        hole = j;
      }
    }
    index_[hole] = kEmpty;
  }

  std::uint64_t keys_[Capacity];  // ring (of limit_ slots) of keys in insertion order, oldest at head_
  V values_[Capacity];            // payload of keys_[i]
  Slot index_[kIndexSize];        // open-addressing index into keys_, or kEmpty
  std::size_t size_ = 0;          // keys held
  std::size_t head_ = 0;          // ring position of the oldest key
  std::size_t limit_ = Capacity;  // keys held at most (set_limit)
};

} // namespace ev3proto
