/// @file ring.hpp
/// @brief The fixed ring every queue of the library is made of: the agent core's datagrams and
///        events, the node's events, the behaviour automaton's outputs, the robot's writes, events,
///        results and reports. No heap, oldest first, with the two policies a full queue needs
///        (refuse the new, or drop the oldest).
#pragma once

#include <cstddef>

namespace ev3proto {

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
    next() = v;
    return commit_over();
  }
  /// The slot the next push_over() writes (when full, the oldest element's): fill it in place,
  /// then commit_over(). Filling it without committing leaves the ring's elements as they are,
  /// but for the oldest one when full.
  T& next() noexcept { return slots_[(head_ + count_) % N]; }
  /// Makes next() the newest element, dropping the oldest when full; true when one was dropped.
  bool commit_over() noexcept {
    const bool full = count_ == N;
    if (full)
      head_ = (head_ + 1) % N;
    else
      ++count_;
    return full;
  }
  /// Takes the oldest element; false when empty.
  bool pop(T& out) noexcept {
    if (count_ == 0) return false;
    out = at(0);
    erase(0);
    return true;
  }
  /// push_over(@p v), counting one more in @p dropped when the oldest was dropped (a queue that
  /// drops the oldest when full and counts what it lost).
  template <typename C>
  void push_over(const T& v, C& dropped) noexcept {
    if (push_over(v)) ++dropped;
  }
  /// The oldest element (!empty()).
  T& front() noexcept { return at(0); }
  /// Removes the oldest element (!empty()).
  void pop_front() noexcept { erase(0); }
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
  /// Forgets every element.
  void clear() noexcept { head_ = count_ = 0; }
  std::size_t size() const noexcept { return count_; }
  bool empty() const noexcept { return count_ == 0; }
  bool full() const noexcept { return count_ == N; }

 private:
  T slots_[N];
  std::size_t head_ = 0, count_ = 0;
};

}  // namespace ev3proto
