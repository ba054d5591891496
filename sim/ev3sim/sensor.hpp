/// @file sensor.hpp
/// @brief Emulation of one ev3dev lego-sensor (touch, colour, ultrasonic, gyro): modes with the
///        driver's value counts, decimals, units and raw formats, the values themselves from what
///        the robot senses, the slow mode change of EV3/UART sensors, the ultrasonic's single-shot
///        lock-up, and a garbage-values fault.
///
/// Mode changes (docs/devices.md, "Sensor modes"): a write to `mode` of a UART sensor returns
/// kModeAckMs later (the driver waits for the sensor's acknowledgement); `mode`, `units`,
/// `decimals`, `num_values` change then; for kModeStaleMs more the values repeat what the new mode
/// read the last time it was active (zeros if never), then they are live. A second mode write while
/// one is in progress fails with EBUSY. Writing a US-SI-* mode sooner than kUsSingleShotGapMs after
/// the previous mode write locks the ultrasonic up: that write fails with ETIMEDOUT after
/// kModeTimeoutMs, and the values freeze for kUsLockupMs (further mode writes time out too).
/// The touch sensor is analog: its one mode is set at once.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>

#include "ev3sim/drivers.hpp"
#include "ev3sim/tree.hpp"
#include "ev3sim/world.hpp"

namespace ev3sim {

/// What a sensor can perceive at one instant (the robot fills it in each step).
struct Perception {
  double distance_cm = -1;   ///< ultrasonic ray: distance to the first obstacle, < 0 when none
  bool heard = false;        ///< another ultrasonic in a continuous mode is in range (US-LISTEN)
  bool pressed = false;      ///< touch
  Colour colour = Colour::None;
  int reflect = 0;           ///< COL-REFLECT
  int ambient = 8;           ///< COL-AMBIENT
  double heading_deg = 0;    ///< robot heading, counter-clockwise (continuous, not wrapped)
  double turn_rate_dps = 0;  ///< counter-clockwise
};

class Sensor {
 public:
  Sensor(const SensorDef& def, Generation gen, std::uint64_t seed);

  const SensorDef& def() const { return *def_; }
  const ModeDef& mode() const { return def_->modes[static_cast<std::size_t>(mode_)]; }

  ReadResult read(std::string_view name) const;
  WriteResult write(std::string_view name, std::string_view data, SimTime now);
  /// Samples what the sensor perceives at @p now (pending mode changes complete first).
  void step(SimTime now, const Perception& p);
  /// Fault: every value a random number over the raw type's whole range (or back to normal).
  void set_garbage(bool on) { garbage_ = on; }
  bool garbage() const { return garbage_; }
  bool locked(SimTime now) const { return now < locked_until_; }
  /// The value shown by valueN (for the status output and tests).
  std::int32_t value(int n) const { return shown_[static_cast<std::size_t>(n)]; }

 private:
  using Values = std::array<std::int32_t, 8>;
  Values measure(int mode, const Perception& p) const;
  std::uint64_t next_random();
  int mode_index(std::string_view name) const;
  bool single_shot(int m) const;

  const SensorDef* def_;
  Generation gen_;
  int mode_ = 0;
  std::array<Values, 8> last_{};  // the last values each mode read
  Values shown_{};
  int pending_mode_ = -1;
  SimTime pending_done_ = 0;
  bool pending_fails_ = false;
  SimTime stale_until_ = 0;
  SimTime last_mode_write_ = -1000000000;
  SimTime locked_until_ = 0;
  bool shot_taken_ = false;       // a single-shot mode has its one measurement
  bool garbage_ = false;
  double gyro_zero_deg_ = 0;      // heading when the angle was last reset
  bool gyro_zero_pending_ = true;
  std::uint64_t rng_;
};

}  // namespace ev3sim
