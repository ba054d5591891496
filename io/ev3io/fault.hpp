/// @file fault.hpp
/// @brief Seeded fault injection for the UDP transport (tests only; off unless a --fault-* flag
///        is given): loss, duplication, reordering and delay of outgoing datagram copies.
///
/// Pure logic, no I/O: given the time a copy is due, schedule() says when (if ever) it really goes
/// out. The same seed and the same sequence of calls give the same schedule.
#pragma once

#include <cstdint>
#include <vector>

#include <ev3proto/timers.hpp>

namespace ev3io {

using ev3proto::Millis;

/// Fault injection parameters (percentages 0..100).
struct FaultConfig {
  double loss = 0;        ///< % of copies dropped.
  double dup = 0;         ///< % of copies sent twice.
  double reorder = 0;     ///< % of copies held back so that later ones overtake them.
  Millis delay_ms = 0;    ///< Every copy is delayed by this much.
  std::uint64_t seed = 1; ///< Seed of the generator.
  /// True when any fault is configured.
  bool enabled() const noexcept { return loss > 0 || dup > 0 || reorder > 0 || delay_ms > 0; }
};

/// Counters of what the injector did.
struct FaultStats {
  std::uint64_t copies = 0, lost = 0, duplicated = 0, reordered = 0, delayed = 0;
};

/// The deterministic fault schedule.
class FaultInjector {
 public:
  /// Extra hold-back of a reordered copy: at least this many ms...
  static constexpr Millis kReorderMinMs = 5;
  /// ...plus up to this many.
  static constexpr Millis kReorderSpreadMs = 45;

  explicit FaultInjector(const FaultConfig& c = {}) noexcept : cfg_(c), state_(c.seed) {}

  /// A copy is due at @p at: appends the times it goes out to @p out (none when lost; two when
  /// duplicated). Without faults, exactly @p at.
  void schedule(Millis at, std::vector<Millis>& out);

  /// The next draw in [0, 100).
  double percent() noexcept;
  /// The next raw 64-bit draw (splitmix64).
  std::uint64_t next() noexcept;

  const FaultConfig& config() const noexcept { return cfg_; }
  const FaultStats& stats() const noexcept { return stats_; }

 private:
  Millis one(Millis at);
  FaultConfig cfg_;
  std::uint64_t state_;
  FaultStats stats_;
};

}  // namespace ev3io
