/// @file device.hpp
/// @brief The device model of an ev3dev brick, as the logic sees it: ports and the other devices
///        (status LEDs, battery), sysfs classes and attributes, driver names, the limits each device
///        states about itself (max_speed, count_per_rot, commands, stop_actions, modes, decimals),
///        fixed-point values, and the parsers that turn the texts of the device files into them.
///
/// Nothing here reads a file: the device layer (io/ev3io/devices.hpp) moves the bytes and the
/// robot logic parses them, so garbage is caught in pure code with a reason naming the file.
#pragma once

#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "text.hpp"

namespace ev3proto::robot {

/// Everything the logic reads or writes: the eight ports, the four brick-status LEDs, the battery.
enum class Dev : std::uint8_t {
  outA, outB, outC, outD, in1, in2, in3, in4,
  led_left_red, led_left_green, led_right_red, led_right_green,
  battery,
};
inline constexpr std::size_t kDevCount = 13;
inline constexpr std::size_t kPortCount = 8;
inline constexpr std::size_t kLedCount = 4;

constexpr std::size_t index(Dev d) noexcept { return static_cast<std::size_t>(d); }
constexpr bool is_port(Dev d) noexcept { return index(d) < kPortCount; }
constexpr bool is_out_port(Dev d) noexcept { return index(d) < 4; }
constexpr bool is_in_port(Dev d) noexcept { return index(d) >= 4 && index(d) < kPortCount; }
constexpr bool is_led(Dev d) noexcept { return index(d) >= 8 && index(d) < 12; }
/// The LED of index 0..3 (left red, left green, right red, right green).
constexpr Dev led_dev(std::size_t i) noexcept { return static_cast<Dev>(8 + i); }

/// ev3dev's port names ("outB", "in1"); the LEDs and the battery by their role.
constexpr std::string_view to_string(Dev d) noexcept {
  constexpr std::string_view kNames[kDevCount] = {
      "outA", "outB", "outC", "outD", "in1", "in2", "in3", "in4",
      "led-left-red", "led-left-green", "led-right-red", "led-right-green", "battery"};
  return index(d) < kDevCount ? kNames[index(d)] : std::string_view{};
}

/// The value among the first @p count of enum E whose to_string() is @p s; false when none is.
template <typename E>
constexpr bool parse_name(std::string_view s, std::size_t count, E& out) noexcept {
  for (std::size_t i = 0; i < count; ++i)
    if (to_string(static_cast<E>(i)) == s) {
      out = static_cast<E>(i);
      return true;
    }
  return false;
}

/// The port named @p s ("outB", "in4"); false for anything else.
constexpr bool parse_port(std::string_view s, Dev& out) noexcept { return parse_name(s, kPortCount, out); }

/// The port of a device's `address` attribute, in both generations of ev3dev: stretch
/// ("ev3-ports:outB", "ev3-ports:in1") and jessie ("outB", "in1"). Addresses of devices behind a
/// port (an I2C sensor "ev3-ports:in1:i2c1", a port's own "ev3-ports:in1:lego-ev3-touch"... ) are
/// not a port of their own: false, as for garbage.
constexpr bool parse_address(std::string_view address, Dev& out) noexcept {
  address = chomp(address);
  constexpr std::string_view kStretch = "ev3-ports:";
  if (address.substr(0, kStretch.size()) == kStretch) address.remove_prefix(kStretch.size());
  return parse_port(address, out);
}

/// The sysfs classes the robot uses (directories under ROOT/class/).
enum class DeviceClass : std::uint8_t { tacho_motor, lego_sensor, leds, power_supply };

constexpr std::string_view to_string(DeviceClass c) noexcept {
  switch (c) {
    case DeviceClass::tacho_motor: return "tacho-motor";
    case DeviceClass::lego_sensor: return "lego-sensor";
    case DeviceClass::leds: return "leds";
    case DeviceClass::power_supply: return "power_supply";
  }
  return {};
}

/// The drivers the robot knows (`driver_name`), both generations spell them alike.
enum class Driver : std::uint8_t {
  unknown,
  ev3_large_motor,   ///< lego-ev3-l-motor
  ev3_medium_motor,  ///< lego-ev3-m-motor
  ev3_ultrasonic,    ///< lego-ev3-us
  ev3_touch,         ///< lego-ev3-touch
  ev3_color,         ///< lego-ev3-color
  ev3_gyro,          ///< lego-ev3-gyro
};

constexpr std::string_view to_string(Driver d) noexcept {
  switch (d) {
    case Driver::unknown: return "unknown";
    case Driver::ev3_large_motor: return "lego-ev3-l-motor";
    case Driver::ev3_medium_motor: return "lego-ev3-m-motor";
    case Driver::ev3_ultrasonic: return "lego-ev3-us";
    case Driver::ev3_touch: return "lego-ev3-touch";
    case Driver::ev3_color: return "lego-ev3-color";
    case Driver::ev3_gyro: return "lego-ev3-gyro";
  }
  return {};
}

/// The driver named @p s (Driver::unknown for any other name).
constexpr Driver parse_driver(std::string_view s) noexcept {
  s = chomp(s);
  for (auto d : {Driver::ev3_large_motor, Driver::ev3_medium_motor, Driver::ev3_ultrasonic,
                 Driver::ev3_touch, Driver::ev3_color, Driver::ev3_gyro})
    if (to_string(d) == s) return d;
  return Driver::unknown;
}

/// The class a driver's devices appear in.
constexpr DeviceClass class_of(Driver d) noexcept {
  return d == Driver::ev3_large_motor || d == Driver::ev3_medium_motor ? DeviceClass::tacho_motor
                                                                       : DeviceClass::lego_sensor;
}

/// The attributes (file names) the robot reads or writes, per class. value0..value7 are
/// consecutive: Attr(value0 + i).
enum class Attr : std::uint8_t {
  // shared by tacho-motor and lego-sensor
  address, driver_name, command, commands,
  // tacho-motor
  count_per_rot, max_speed, position, position_sp, speed, speed_sp, time_sp, state, stop_action,
  stop_actions, polarity,
  // lego-sensor
  mode, modes, num_values, decimals, units, poll_ms,
  value0, value1, value2, value3, value4, value5, value6, value7,
  // leds
  brightness, max_brightness, trigger, delay_on, delay_off,
  // power_supply
  voltage_now, current_now,
};
inline constexpr std::size_t kAttrCount = static_cast<std::size_t>(Attr::current_now) + 1;

/// The file name of an attribute ("speed_sp").
constexpr std::string_view to_string(Attr a) noexcept {
  constexpr std::string_view kNames[kAttrCount] = {
      "address", "driver_name", "command", "commands",
      "count_per_rot", "max_speed", "position", "position_sp", "speed", "speed_sp", "time_sp", "state",
      "stop_action", "stop_actions", "polarity",
      "mode", "modes", "num_values", "decimals", "units", "poll_ms",
      "value0", "value1", "value2", "value3", "value4", "value5", "value6", "value7",
      "brightness", "max_brightness", "trigger", "delay_on", "delay_off",
      "voltage_now", "current_now"};
  const auto i = static_cast<std::size_t>(a);
  return i < kAttrCount ? kNames[i] : std::string_view{};
}

/// The attribute named @p s; false for a name the robot does not use.
constexpr bool parse_attr(std::string_view s, Attr& out) noexcept { return parse_name(s, kAttrCount, out); }

/// value0 + @p i (i < 8).
constexpr Attr value_attr(std::size_t i) noexcept {
  return static_cast<Attr>(static_cast<std::size_t>(Attr::value0) + (i < 8 ? i : 7));
}

/// The most values a lego-sensor gives (num_values <= 8: value0..value7).
inline constexpr std::size_t kMaxValues = 8;

/// The name of an errno value a device file may answer with ("EBUSY"); "error" for others.
constexpr std::string_view errno_name(int e) noexcept {
  switch (e) {
    case EBUSY: return "EBUSY";
    case EINVAL: return "EINVAL";
    case EIO: return "EIO";
    case ENODEV: return "ENODEV";
    case ENOENT: return "ENOENT";
    case ENXIO: return "ENXIO";
    case ETIMEDOUT: return "ETIMEDOUT";
    case EAGAIN: return "EAGAIN";
    case EACCES: return "EACCES";
    case EPERM: return "EPERM";
    case EOPNOTSUPP: return "EOPNOTSUPP";
    default: return "error";
  }
}

// ------------------------------------------------------------------ fixed point

/// A sensor value as ev3dev gives it: raw / 10^decimals (US-DIST-CM 183 with decimals 1 = 18.3 cm).
struct Fixed {
  std::int32_t raw = 0;
  std::uint8_t decimals = 0;

  /// -1, 0, 1 as this value is below, equal to, above @p o (exact, whatever the decimals).
  constexpr int compare(Fixed o) const noexcept {
    std::int64_t a = raw, b = o.raw;
    for (unsigned d = decimals; d < o.decimals; ++d) a *= 10;
    for (unsigned d = o.decimals; d < decimals; ++d) b *= 10;
    return a < b ? -1 : a > b ? 1 : 0;
  }
  constexpr bool operator<(Fixed o) const noexcept { return compare(o) < 0; }
  constexpr bool operator>=(Fixed o) const noexcept { return compare(o) >= 0; }
  constexpr bool operator==(Fixed o) const noexcept { return compare(o) == 0; }
  /// The value with @p o added (in the finer of the two scales).
  constexpr Fixed plus(Fixed o) const noexcept {
    Fixed a = *this;
    while (a.decimals < o.decimals) {
      a.raw *= 10;
      ++a.decimals;
    }
    std::int32_t b = o.raw;
    for (unsigned d = o.decimals; d < a.decimals; ++d) b *= 10;
    a.raw += b;
    return a;
  }
};

/// Largest decimals value accepted from a device (ev3dev uses 0..3; 9 keeps 10^d in int32).
inline constexpr std::uint8_t kMaxDecimals = 9;

// ------------------------------------------------------------------ motors

/// ev3dev's tacho-motor commands (the `command` attribute). run-direct is listed for the check of
/// `commands` only: the robot never uses it.
enum class MotorCommand : std::uint8_t { run_forever, run_to_abs_pos, run_to_rel_pos, run_timed, run_direct, stop, reset };
inline constexpr std::size_t kMotorCommandCount = 7;

constexpr std::string_view to_string(MotorCommand c) noexcept {
  constexpr std::string_view kNames[kMotorCommandCount] = {
      "run-forever", "run-to-abs-pos", "run-to-rel-pos", "run-timed", "run-direct", "stop", "reset"};
  const auto i = static_cast<std::size_t>(c);
  return i < kMotorCommandCount ? kNames[i] : std::string_view{};
}
constexpr bool parse_motor_command(std::string_view s, MotorCommand& out) noexcept {
  return parse_name(s, kMotorCommandCount, out);
}
constexpr std::uint8_t bit(MotorCommand c) noexcept { return static_cast<std::uint8_t>(1u << static_cast<unsigned>(c)); }

/// ev3dev's stop actions (`stop_action`).
enum class StopAction : std::uint8_t { coast, brake, hold };

constexpr std::string_view to_string(StopAction s) noexcept {
  switch (s) {
    case StopAction::coast: return "coast";
    case StopAction::brake: return "brake";
    case StopAction::hold: return "hold";
  }
  return {};
}
constexpr bool parse_stop_action(std::string_view s, StopAction& out) noexcept { return parse_name(s, 3, out); }
constexpr std::uint8_t bit(StopAction s) noexcept { return static_cast<std::uint8_t>(1u << static_cast<unsigned>(s)); }

/// The flags of a motor's `state` ("running ramping", "holding", "" when idle).
enum MotorState : std::uint8_t {
  kRunning = 1u << 0, kRamping = 1u << 1, kHolding = 1u << 2, kOverloaded = 1u << 3, kStalled = 1u << 4,
};

/// Parses `state`: a space-separated set of running, ramping, holding, overloaded, stalled (empty
/// when the motor is idle). False for any other word.
constexpr bool parse_motor_state(std::string_view s, std::uint8_t& flags) noexcept {
  std::uint8_t f = 0;
  for (Tokens t(s); !t.done(); t.next()) {
    const std::string_view w = t.token();
    if (w == "running") f |= kRunning;
    else if (w == "ramping") f |= kRamping;
    else if (w == "holding") f |= kHolding;
    else if (w == "overloaded") f |= kOverloaded;
    else if (w == "stalled") f |= kStalled;
    else return false;
  }
  flags = f;
  return true;
}

/// What a tacho-motor says about itself when it appears (read once, at discovery).
struct MotorInfo {
  Driver driver = Driver::unknown;
  std::int32_t max_speed = 0;      ///< counts per second (speed_sp must stay within +-max_speed)
  std::int32_t count_per_rot = 0;  ///< tacho counts per rotation (360 for the EV3 motors)
  std::uint8_t commands = 0;       ///< bits of MotorCommand the motor lists in `commands`
  std::uint8_t stop_actions = 0;   ///< bits of StopAction it lists in `stop_actions`
};

// ------------------------------------------------------------------ sensors

/// A sensor mode name ("US-DIST-CM"): ev3dev's are at most 10 characters.
using ModeName = Text<16>;
/// The most modes a sensor lists that are kept (the EV3 sensors list at most 8).
inline constexpr std::size_t kMaxModes = 12;

/// What a lego-sensor says about itself (read at discovery and again after each mode change:
/// decimals, num_values and units depend on the mode).
struct SensorInfo {
  Driver driver = Driver::unknown;
  ModeName modes[kMaxModes];
  std::uint8_t mode_count = 0;
  std::int8_t mode = -1;           ///< index of the current mode in modes (-1: not one of them)
  std::uint8_t decimals = 0;
  std::uint8_t num_values = 0;
  Text<8> units;

  /// Index of mode @p m in `modes`, -1 when the sensor does not list it.
  constexpr int find_mode(std::string_view m) const noexcept {
    for (std::size_t i = 0; i < mode_count; ++i)
      if (modes[i].view() == m) return static_cast<int>(i);
    return -1;
  }
  constexpr std::string_view mode_name() const noexcept {
    return mode >= 0 && static_cast<std::size_t>(mode) < mode_count ? modes[static_cast<std::size_t>(mode)].view()
                                                                    : std::string_view{};
  }
};

// ------------------------------------------------------------------ devices

/// A device found on a port, as the device layer reports it (DeviceLayer::scan).
struct DeviceInfo {
  Dev dev = Dev::outA;
  DeviceClass cls = DeviceClass::tacho_motor;
  Driver driver = Driver::unknown;
  Text<24> driver_name;  ///< as read (also when the driver is unknown to the robot)
  MotorInfo motor;       ///< cls == tacho_motor
  SensorInfo sensor;     ///< cls == lego_sensor
};

/// Sets @p why to "FILE 'TEXT' WHAT" and returns false.
constexpr bool bad_file(ReasonText& why, std::string_view file, std::string_view text, std::string_view what) noexcept {
  why.clear();
  why.append(file).append(" ");
  append_quoted(why, text);
  why.append(" ").append(what);
  return false;
}

/// The texts of a tacho-motor's self-description, as read from its files.
struct MotorTexts {
  std::string_view driver_name, max_speed, count_per_rot, commands, stop_actions;
};

/// Builds MotorInfo from the texts of a motor's files. False, with @p why naming the file and the
/// bad text, when one is garbage (a motor that does not list `stop`, a max_speed of 0 ...).
constexpr bool parse_motor_info(const MotorTexts& t, MotorInfo& out, ReasonText& why) noexcept {
  MotorInfo m;
  m.driver = parse_driver(t.driver_name);
  auto bad = [&why](std::string_view file, std::string_view text, std::string_view what) {
    return bad_file(why, file, text, what);
  };
  if (!parse_int(t.max_speed, m.max_speed) || m.max_speed <= 0)
    return bad("max_speed", t.max_speed, "is not a positive number");
  if (!parse_int(t.count_per_rot, m.count_per_rot) || m.count_per_rot <= 0)
    return bad("count_per_rot", t.count_per_rot, "is not a positive number");
  for (Tokens k(t.commands); !k.done(); k.next()) {
    MotorCommand c{};
    if (!parse_motor_command(k.token(), c)) return bad("commands", t.commands, "lists an unknown command");
    m.commands = static_cast<std::uint8_t>(m.commands | bit(c));
  }
  if ((m.commands & bit(MotorCommand::stop)) == 0) return bad("commands", t.commands, "does not list stop");
  for (Tokens k(t.stop_actions); !k.done(); k.next()) {
    StopAction s{};
    if (!parse_stop_action(k.token(), s)) return bad("stop_actions", t.stop_actions, "lists an unknown stop action");
    m.stop_actions = static_cast<std::uint8_t>(m.stop_actions | bit(s));
  }
  if (m.stop_actions == 0) return bad("stop_actions", t.stop_actions, "lists no stop action");
  out = m;
  return true;
}

/// The texts of a lego-sensor's self-description.
struct SensorTexts {
  std::string_view driver_name, modes, mode, decimals, num_values, units;
};

/// The mode-dependent part of a sensor (decimals, num_values, units, current mode) from its texts.
constexpr bool parse_sensor_mode(const SensorTexts& t, SensorInfo& s, ReasonText& why) noexcept {
  auto bad = [&why](std::string_view file, std::string_view text, std::string_view what) {
    return bad_file(why, file, text, what);
  };
  std::int32_t d = 0, n = 0;
  if (!parse_int(t.decimals, d) || d < 0 || d > kMaxDecimals) return bad("decimals", t.decimals, "is not 0..9");
  if (!parse_int(t.num_values, n) || n < 0 || n > static_cast<std::int32_t>(kMaxValues))
    return bad("num_values", t.num_values, "is not 0..8");
  const int m = s.find_mode(chomp(t.mode));
  if (m < 0) return bad("mode", t.mode, "is not one of the modes listed");
  s.decimals = static_cast<std::uint8_t>(d);
  s.num_values = static_cast<std::uint8_t>(n);
  s.mode = static_cast<std::int8_t>(m);
  s.units = Text<8>(chomp(t.units));
  return true;
}

/// Builds SensorInfo from the texts of a sensor's files (see parse_motor_info).
constexpr bool parse_sensor_info(const SensorTexts& t, SensorInfo& out, ReasonText& why) noexcept {
  SensorInfo s;
  s.driver = parse_driver(t.driver_name);
  for (Tokens k(t.modes); !k.done(); k.next()) {
    if (s.mode_count == kMaxModes || k.token().size() >= 16 || !is_word(k.token()))
      return bad_file(why, "modes", t.modes, "is not a list of mode names");
    s.modes[s.mode_count++] = ModeName(k.token());
  }
  if (s.mode_count == 0) {
    why.clear();
    why.append("modes lists no mode");
    return false;
  }
  if (!parse_sensor_mode(t, s, why)) return false;
  out = s;
  return true;
}

}  // namespace ev3proto::robot
