/// @file ring.hpp
/// @brief The fixed ring every robot queue is made of (writes, events, results, reports): no heap,
///        oldest first, with the two policies a full queue needs (refuse the new, or drop the oldest).
#pragma once

#include <cstddef>

namespace ev3proto::robot {

template <typename T, std::size_t N>
class Ring {
 public:
  static_assert(N >= 1, "a ring holds at least one element");
  /// Appends @p v; false (nothing changed) when full.
  bool push(const T& v) noexcept {
    if (count_ == N) return false;
    at(count_++) = v;
    return true;
  }
  /// Appends @p v, dropping the oldest element when full; true when one was dropped.
  bool push_over(const T& v) noexcept {
    const bool full = count_ == N;
    if (full) erase(0);
    push(v);
    return full;
  }
  /// Takes the oldest element; false when empty.
  bool pop(T& out) noexcept {
    if (count_ == 0) return false;
    out = at(0);
    erase(0);
    return true;
  }
  /// Element @p i, 0 the oldest (i < size()).
  T& at(std::size_t i) noexcept { return slots_[(head_ + i) % N]; }
  const T& at(std::size_t i) const noexcept { return slots_[(head_ + i) % N]; }
  /// Removes element @p i, keeping the order of the others.
  void erase(std::size_t i) noexcept {
    if (i == 0) {
      head_ = (head_ + 1) % N;
    } else {
      for (std::size_t k = i; k + 1 < count_; ++k) at(k) = at(k + 1);
    }
    --count_;
  }
  /// Keeps only the elements for which @p keep is true, in order.
  template <typename F>
  void filter(F keep) noexcept {
    std::size_t kept = 0;
    for (std::size_t i = 0; i < count_; ++i)
      if (keep(at(i))) at(kept++) = at(i);
    count_ = kept;
  }
  std::size_t size() const noexcept { return count_; }
  bool empty() const noexcept { return count_ == 0; }
  bool full() const noexcept { return count_ == N; }

 private:
  T slots_[N];
  std::size_t head_ = 0, count_ = 0;
};

}  // namespace ev3proto::robot
