/// @file events.hpp
/// @brief Robot events (thesis 5.2.2): one queue, many producers (device presence, the sensor
///        detectors, the runtime), one consumer (the Runtime, which reacts and hands them on to
///        feed the agent core and to be sent to the master as EVENT, name first).
///
/// Normal events inform or warn: DEVICE_CONNECTED (port, driver), PROXIMITY_ALERT (ultrasonic below
/// a threshold), OBSTACLE_DETECTED (touch pressed), DEVICE_ERROR (a device gave garbage or is not
/// what the model expects: a reported exception). Critical ones stop activity: DEVICE_DISCONNECTED
/// (port; stops what needs the device), BATTERY_LOW (motors stopped, master told, clean exit).
///
/// The detectors are edge-triggered and debounced: a held bumper is one OBSTACLE_DETECTED, an
/// obstacle standing in front of the ultrasonic one PROXIMITY_ALERT, until it goes away.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "../timers.hpp"
#include "device.hpp"
#include "../ring.hpp"
#include "text.hpp"

namespace ev3proto::robot {

using ev3proto::Millis;

/// The robot's events. The names are the ones sent in EVENT.
enum class EventKind : std::uint8_t {
  DEVICE_CONNECTED, PROXIMITY_ALERT, OBSTACLE_DETECTED, DEVICE_ERROR,  // normal
  DEVICE_DISCONNECTED, BATTERY_LOW,                                     // critical
};
inline constexpr std::size_t kEventKindCount = 6;

constexpr std::string_view to_string(EventKind k) noexcept {
  constexpr std::string_view kNames[kEventKindCount] = {"DEVICE_CONNECTED", "PROXIMITY_ALERT", "OBSTACLE_DETECTED",
                                                        "DEVICE_ERROR", "DEVICE_DISCONNECTED", "BATTERY_LOW"};
  const auto i = static_cast<std::size_t>(k);
  return i < kEventKindCount ? kNames[i] : std::string_view{};
}

/// Normal events inform or warn; critical ones stop some or all activity (thesis 5.2.2).
enum class Severity : std::uint8_t { normal, critical };

constexpr Severity severity_of(EventKind k) noexcept {
  return k == EventKind::DEVICE_DISCONNECTED || k == EventKind::BATTERY_LOW ? Severity::critical : Severity::normal;
}

/// A set of event kinds (which events interrupt an action).
using EventSet = std::uint8_t;
constexpr EventSet event_bit(EventKind k) noexcept { return static_cast<EventSet>(1u << static_cast<unsigned>(k)); }
constexpr bool contains(EventSet s, EventKind k) noexcept { return (s & event_bit(k)) != 0; }

/// One event. `dev` is the port (DEVICE_*, PROXIMITY_ALERT, OBSTACLE_DETECTED) or Dev::battery;
/// `detail` what else the master should know (driver name, distance, voltage, the bad value).
struct Event {
  EventKind kind = EventKind::DEVICE_CONNECTED;
  Dev dev = Dev::outA;
  Millis at = 0;
  std::uint32_t bits = 0;  ///< the model's device bits this event is about (0: none of its devices)
  bool interrupted = false;  ///< it interrupted the running action (the runtime's result says so)
  Text<128> detail;

  Severity severity() const noexcept { return severity_of(kind); }
  /// The EVENT parameters: name, then the port (not for BATTERY_LOW), then the detail if any.
  /// Returns how many of @p out (at least 3) it filled.
  std::size_t params(std::string_view* out) const noexcept {
    std::size_t n = 0;
    out[n++] = to_string(kind);
    if (is_port(dev)) out[n++] = to_string(dev);
    if (!detail.empty()) out[n++] = detail.view();
    return n;
  }
};

/// The one event queue: a fixed ring of N events. pop() gives the oldest critical event first,
/// then the oldest normal one. Full: a new normal event is dropped; a new critical one replaces
/// the oldest normal event (or, when every slot is critical, the oldest); drops are counted.
template <std::size_t N = 16>
class EventQueue {
 public:
  void push(const Event& e) noexcept {
    if (ring_.full()) {
      ++dropped_;
      if (e.severity() == Severity::normal) return;
      ring_.erase(oldest(Severity::normal));  // or, when every slot is critical, the oldest
    }
    ring_.push(e);
  }
  bool pop(Event& out) noexcept {
    if (ring_.empty()) return false;
    const std::size_t i = oldest(Severity::critical);
    out = ring_.at(i);
    ring_.erase(i);
    return true;
  }
  std::size_t size() const noexcept { return ring_.size(); }
  bool empty() const noexcept { return ring_.empty(); }
  std::size_t dropped() const noexcept { return dropped_; }

 private:
  /// The oldest event of severity @p s, or 0 (the oldest of all) when there is none.
  std::size_t oldest(Severity s) const noexcept {
    for (std::size_t i = 0; i < ring_.size(); ++i)
      if (ring_.at(i).severity() == s) return i;
    return 0;
  }
  Ring<Event, N> ring_;
  std::size_t dropped_ = 0;
};

// ------------------------------------------------------------------ detectors

/// The touch bumper: OBSTACLE_DETECTED on a press, once per press. A release counts only after it
/// has lasted `release_ms` (a bouncing contact is one press); the first reading after the sensor
/// appears counts as an edge from released (a robot started against a wall hears about it).
class TouchEdge {
 public:
  Millis release_ms = 50;

  /// A reading: true = pressed. Returns true when this is a new press.
  bool update(bool pressed, Millis now) noexcept {
    if (pressed) {
      released_since_ = kNone;
      if (held_) return false;
      held_ = true;
      return true;
    }
    if (!held_) return false;
    if (released_since_ == kNone) released_since_ = now;
    if (now - released_since_ >= release_ms) held_ = false;
    return false;
  }
  /// Forget the state (the sensor was unplugged).
  void reset() noexcept {
    held_ = false;
    released_since_ = kNone;
  }
  bool held() const noexcept { return held_; }

 private:
  static constexpr Millis kNone = ~Millis{0};
  bool held_ = false;
  Millis released_since_ = kNone;
};

/// The forward ultrasonic: PROXIMITY_ALERT when the distance has been below `threshold` in
/// `confirm` consecutive readings (one stray echo is no obstacle), once, until the distance has
/// risen to `threshold + hysteresis` again.
class ProximityWatch {
 public:
  Fixed threshold{200, 1};   ///< 20.0 cm
  Fixed hysteresis{50, 1};   ///< re-armed at 25.0 cm
  std::uint8_t confirm = 2;  ///< readings in a row

  /// A distance reading (cm). Returns true when it raises the alert.
  bool update(Fixed cm) noexcept {
    if (cm < threshold) {
      if (alerted_) return false;
      if (++below_ < confirm) return false;
      alerted_ = true;
      return true;
    }
    below_ = 0;
    if (alerted_ && cm >= threshold.plus(hysteresis)) alerted_ = false;
    return false;
  }
  void reset() noexcept {
    alerted_ = false;
    below_ = 0;
  }
  bool alerted() const noexcept { return alerted_; }

 private:
  bool alerted_ = false;
  std::uint8_t below_ = 0;
};

/// The battery: BATTERY_LOW once the voltage has stayed below `threshold_uv` for `hold_ms` (the
/// voltage sags while the motors start; a short dip is no empty battery). Latched: it fires once.
/// Default 6.2 V: LEGO's own firmware (lms2012 bytecodes.h) starts warning at 6.2 V on AA cells
/// (shuts down at 4.5-5.5 V) and shuts the rechargeable pack down at 6.0-6.5 V; 6.2 V leaves time
/// for a clean exit on both.
class BatteryWatch {
 public:
  std::int32_t threshold_uv = 6200000;  ///< 6.2 V
  Millis hold_ms = 3000;

  /// A reading of voltage_now (µV). Returns true when it raises BATTERY_LOW.
  bool update(std::int32_t uv, Millis now) noexcept {
    if (fired_) return false;
    if (uv >= threshold_uv) {
      below_since_ = kNone;
      return false;
    }
    if (below_since_ == kNone) below_since_ = now;
    if (now - below_since_ < hold_ms) return false;
    fired_ = true;
    return true;
  }
  bool fired() const noexcept { return fired_; }

 private:
  static constexpr Millis kNone = ~Millis{0};
  Millis below_since_ = kNone;
  bool fired_ = false;
};

}  // namespace ev3proto::robot
