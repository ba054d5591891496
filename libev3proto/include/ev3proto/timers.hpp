/// @file timers.hpp
/// @brief The one table of named protocol deadlines (agent and master), with their defaults.
///
/// The spec (spec/tla/AgentLogic.tla, Fleet.tla) counts time in ticks: TSync, TPing, TLoss, TPaused,
/// TDrop, and the master resends a pending command every tick. The cores count monotonic
/// milliseconds. A core configured with every timer equal to the model's constant (and resend = 1)
/// behaves as the spec with 1 tick = 1 ms: `advance(now + 1)` is one spec Tick. docs/core.md has
/// the full mapping.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace ev3proto {

/// Monotonic time in milliseconds, as the caller's clock gives it (any origin).
using Millis = std::uint64_t;

/// The named deadlines of the protocol. The numeric values index Timers::ms and kTimerTable.
enum class Timer : std::uint8_t {
  sync,      ///< Agent: IDLE this long without a MASTER -> PANIC (spec TSync).
  heartbeat, ///< Agent: period of AGENT (IDLE), PING (synced) and PANIC broadcasts (spec TPing).
  loss,      ///< Agent: master not heard this long: ACTIVE -> PANIC, WORKING -> PAUSED (spec TLoss).
  paused,    ///< Agent: master not heard this long in PAUSED -> PANIC (spec TPaused, > loss).
  resend,    ///< Master: a pending command is resent at this interval (spec: every tick).
  drop,      ///< Master: an agent not heard this long leaves the registry (spec TDrop).
  relay_retry, ///< Agent in PANIC: period of RELAY_REQ (Election RequestRelay).
  backoff,     ///< Agent in PANIC: wait before standing (Election StartElection); grows with rank.
  backoff_step, ///< Agent: back-off added per weaker peer heard asking (weakest stands first).
  backoff_jitter, ///< Agent: a random back-off in [0, this) on top (raft's randomised timeout).
  candidate,   ///< Candidate without a majority this long stands again in epoch + 1.
  leader_heartbeat, ///< Master (PC or elected agent): period of LEADER (Election Heartbeat).
  vouch,       ///< Agent: offers a relay only for a master heard this recently; refuses, this long
               ///< after declaring its master lost, a relay to that master (0: neither rule).
};

/// Number of named timers.
inline constexpr std::size_t kTimerCount = 13;

/// One row of the timer table: the timer, its name, the spec constant it stands for, its default.
struct TimerSpec {
  Timer timer;                ///< Which timer.
  std::string_view name;      ///< Name used in configuration and docs ("loss").
  std::string_view spec_name; ///< The TLA+ constant it corresponds to ("TLoss").
  Millis default_ms;          ///< Default in milliseconds (with the default heartbeat, 100 ms).
  /// Hundredths of the heartbeat it is (800: 8 heartbeats); 0: fixed, not scaled
  /// (Timers::for_heartbeat).
  std::uint32_t heartbeat_pct;
  std::string_view meaning;   ///< One line of documentation.
};

/// The default heartbeat (agents' PING period), in milliseconds: etcd's 100 ms.
inline constexpr Millis kDefaultHeartbeatMs = 100;

/// The timer table: the single place where protocol timeouts are defined (docs/core.md prints it).
/// Every timer but sync is a multiple of the heartbeat; docs/election.md "Timers" gives the reasons.
inline constexpr std::array<TimerSpec, kTimerCount> kTimerTable{{
    {Timer::sync, "sync", "TSync", 10000, 0, "IDLE without MASTER -> PANIC (thesis: 10 s)"},
    {Timer::heartbeat, "heartbeat", "TPing", 100, 100, "period of AGENT / PING / PANIC broadcasts"},
    {Timer::loss, "loss", "TLoss", 800, 800, "master silent: ACTIVE -> PANIC, WORKING -> PAUSED"},
    {Timer::paused, "paused", "TPaused", 1000, 1000, "master silent in PAUSED -> PANIC (> loss)"},
    {Timer::resend, "resend", "1 tick", 500, 500, "master resends a pending command"},
    {Timer::drop, "drop", "TDrop", 10000, 10000, "master forgets an agent not heard for this long"},
    {Timer::relay_retry, "relay_retry", "RequestRelay", 200, 200, "PANIC: RELAY_REQ period (first one at once)"},
    {Timer::backoff, "backoff", "StartElection", 200, 200, "PANIC this long without relay -> stand (+ rank, jitter)"},
    {Timer::backoff_step, "backoff_step", "Score", 100, 100, "back-off per weaker peer heard (weakest stands first)"},
    {Timer::backoff_jitter, "backoff_jitter", "StartElection", 50, 50, "random back-off on top, in [0, this)"},
    {Timer::candidate, "candidate", "StartElection", 200, 200, "no majority this long -> stand again, epoch + 1"},
    {Timer::leader_heartbeat, "leader_heartbeat", "Heartbeat", 100, 100, "period of a master's LEADER"},
    {Timer::vouch, "vouch", "OfferRelay", 200, 200, "relay offered only for a master heard this recently (0: off)"},
}};

/// True for the timers 0 turns off (backoff_jitter, vouch); every other is at least 1 ms.
constexpr bool zero_turns_off(Timer t) noexcept { return t == Timer::backoff_jitter || t == Timer::vouch; }

/// Values of all timers, in milliseconds; default-constructed with kTimerTable's defaults.
struct Timers {
  std::array<Millis, kTimerCount> ms{}; ///< ms[static_cast<size_t>(Timer::x)] is timer x.

  /// All timers at their defaults.
  constexpr Timers() noexcept {
    for (std::size_t i = 0; i < kTimerCount; ++i) ms[i] = kTimerTable[i].default_ms;
  }
  /// The value of timer @p t.
  constexpr Millis operator[](Timer t) const noexcept { return ms[static_cast<std::size_t>(t)]; }
  /// Sets timer @p t to @p value (0 is replaced by 1: every timer is at least one tick), except
  /// those 0 turns off (zero_turns_off).
  constexpr Timers& set(Timer t, Millis value) noexcept {
    ms[static_cast<std::size_t>(t)] = value == 0 && !zero_turns_off(t) ? 1 : value;
    return *this;
  }
  /// True when the values satisfy the spec's assumptions (all > 0 but those 0 turns off, paused >
  /// loss).
  constexpr bool valid() const noexcept {
    for (std::size_t i = 0; i < kTimerCount; ++i)
      if (ms[i] == 0 && !zero_turns_off(kTimerTable[i].timer)) return false;
    return (*this)[Timer::paused] > (*this)[Timer::loss];
  }
  /// Every timer scaled to heartbeat @p heartbeat_ms by the table's heartbeat_pct (sync stays as
  /// it is; each at least 1 ms): `--heartbeat-ms` moves them all.
  static constexpr Timers for_heartbeat(Millis heartbeat_ms) noexcept {
    Timers t;
    for (std::size_t i = 0; i < kTimerCount; ++i) {
      const TimerSpec& s = kTimerTable[i];
      if (s.heartbeat_pct == 0) continue;
      const Millis v = heartbeat_ms * s.heartbeat_pct / 100;
      t.ms[i] = v == 0 ? 1 : v;
    }
    return t;
  }
  /// Timers equal to a model's constants with 1 tick = 1 ms (resend every tick, as Fleet.tla).
  static constexpr Timers from_ticks(Millis t_sync, Millis t_ping, Millis t_loss, Millis t_paused,
                                     Millis t_drop) noexcept {
    Timers t;
    t.set(Timer::sync, t_sync).set(Timer::heartbeat, t_ping).set(Timer::loss, t_loss);
    t.set(Timer::paused, t_paused).set(Timer::resend, 1).set(Timer::drop, t_drop);
    return t;
  }
};

/// Name of a timer as in kTimerTable ("loss").
constexpr std::string_view to_string(Timer t) noexcept {
  return kTimerTable[static_cast<std::size_t>(t)].name;
}

static_assert(Timers{}.valid(), "the default timers must satisfy the spec's assumptions");

namespace detail {
constexpr bool scaled_defaults() noexcept {
  const Timers d, s = Timers::for_heartbeat(kDefaultHeartbeatMs);
  for (std::size_t i = 0; i < kTimerCount; ++i)
    if (d.ms[i] != s.ms[i]) return false;
  return true;
}
}  // namespace detail
static_assert(detail::scaled_defaults(), "the defaults are the table's multiples of the default heartbeat");

/// A core's armed deadlines, one per kind (quinn-proto's TimerTable): an array indexed by @p Kind
/// (an enum whose values are 0..N-1). Arming, stopping and reading a timer are O(1); the earliest
/// deadline is O(N). No heap.
template <typename Kind, std::size_t N>
class TimerTable {
 public:
  /// "Not armed".
  static constexpr Millis kNever = ~Millis{0};

  /// Every timer stopped.
  constexpr TimerTable() noexcept {
    for (Millis& t : at_) t = kNever;
  }
  /// Arms timer @p k for time @p at (kNever stops it).
  constexpr void set(Kind k, Millis at) noexcept { at_[index(k)] = at; }
  /// Stops timer @p k.
  constexpr void stop(Kind k) noexcept { at_[index(k)] = kNever; }
  /// When timer @p k is due (kNever when stopped).
  constexpr Millis get(Kind k) const noexcept { return at_[index(k)]; }
  /// True when timer @p k is armed and due at @p now.
  constexpr bool due(Kind k, Millis now) const noexcept { return at_[index(k)] <= now; }
  /// The earliest armed deadline (kNever when none is armed).
  constexpr Millis next() const noexcept {
    Millis t = kNever;
    for (Millis a : at_)
      if (a < t) t = a;
    return t;
  }

 private:
  static constexpr std::size_t index(Kind k) noexcept { return static_cast<std::size_t>(k); }
  std::array<Millis, N> at_{};
};

}  // namespace ev3proto
