/// @file model.hpp
/// @brief Model A, the thesis' test robot: which device plays which role on which port, the
///        geometry of its drive base, its device bits (the agent core's Capabilities::devices),
///        and the parsing of `--ports`.
///
/// Model A (brief sec. 6, docs/devices.md "Model A"): a differential drive of two EV3 large motors,
/// left on outB and right on outC; a touch sensor behind the front bumper on in1; a colour sensor
/// facing the floor on in3; an ultrasonic sensor facing forward on in4. `--ports` moves any role.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "device.hpp"
#include "text.hpp"

namespace ev3proto::robot {

/// A device's part in a robot. The behaviour language names devices by these too
/// (behaviour/model.hpp): a behaviour that reads the gyro needs a robot with one.
enum class Role : std::uint8_t { left, right, ultrasonic, touch, colour, gyro };
/// The roles model A has a port for: every role but gyro (PortMap, `--ports`).
inline constexpr std::size_t kRoleCount = 5;
/// Every role, gyro included.
inline constexpr std::size_t kAllRoleCount = 6;

/// The role's name as `--ports` spells it (left, right, ultrasonic, touch, colour; gyro).
constexpr std::string_view to_string(Role r) noexcept {
  constexpr std::string_view kNames[kAllRoleCount] = {"left", "right", "ultrasonic", "touch", "colour", "gyro"};
  const auto i = static_cast<std::size_t>(r);
  return i < kAllRoleCount ? kNames[i] : std::string_view{};
}

/// The device that plays the role, as messages name it ("the robot has no colour sensor").
constexpr std::string_view device_name(Role r) noexcept {
  constexpr std::string_view kNames[kAllRoleCount] = {"left motor",   "right motor",   "ultrasonic sensor",
                                                      "touch sensor", "colour sensor", "gyro sensor"};
  const auto i = static_cast<std::size_t>(r);
  return i < kAllRoleCount ? kNames[i] : std::string_view{"?"};
}

/// The device bit of a role in the agent core's Capabilities::devices (the same bits ev3-agent
/// announces today: left 1, right 2, ultrasonic 4, touch 8, colour 16).
constexpr std::uint32_t role_bit(Role r) noexcept { return 1u << static_cast<unsigned>(r); }
inline constexpr std::uint32_t kMotorLeft = role_bit(Role::left);
inline constexpr std::uint32_t kMotorRight = role_bit(Role::right);
inline constexpr std::uint32_t kUltrasonic = role_bit(Role::ultrasonic);
inline constexpr std::uint32_t kTouch = role_bit(Role::touch);
inline constexpr std::uint32_t kColour = role_bit(Role::colour);
inline constexpr std::uint32_t kMotors = kMotorLeft | kMotorRight;
/// Every device of model A.
inline constexpr std::uint32_t kModelADevices = kMotors | kUltrasonic | kTouch | kColour;
/// The name of each device bit of model A (index: the role), for the agent core's NOT "missing
/// device: the robot has no colour sensor (explore needs it)" (Capabilities::device_names).
inline constexpr std::string_view kModelADeviceNames[kRoleCount] = {
    device_name(Role::left), device_name(Role::right), device_name(Role::ultrasonic), device_name(Role::touch),
    device_name(Role::colour)};

/// The driver a role's device must have.
constexpr Driver driver_of(Role r) noexcept {
  switch (r) {
    case Role::left:
    case Role::right: return Driver::ev3_large_motor;
    case Role::ultrasonic: return Driver::ev3_ultrasonic;
    case Role::touch: return Driver::ev3_touch;
    case Role::colour: return Driver::ev3_color;
    case Role::gyro: return Driver::ev3_gyro;
  }
  return Driver::unknown;
}

/// The mode model A keeps each sensor in ("" for the motors): distance in cm forward, the bumper,
/// the colour code of the floor (0 none, 1 black, 2 blue, 3 green, 4 yellow, 5 red, 6 white, 7 brown).
constexpr std::string_view default_mode(Role r) noexcept {
  switch (r) {
    case Role::ultrasonic: return "US-DIST-CM";
    case Role::touch: return "TOUCH";
    case Role::colour: return "COL-COLOR";
    default: return {};
  }
}

/// Which port each role is on.
struct PortMap {
  Dev port[kRoleCount] = {Dev::outB, Dev::outC, Dev::in4, Dev::in1, Dev::in3};

  constexpr Dev of(Role r) const noexcept { return port[static_cast<std::size_t>(r)]; }
  /// The role on port @p d; false when no role is there.
  constexpr bool role_on(Dev d, Role& out) const noexcept {
    for (std::size_t i = 0; i < kRoleCount; ++i)
      if (port[i] == d) {
        out = static_cast<Role>(i);
        return true;
      }
    return false;
  }
};

/// Parses `--ports`: comma-separated role=port pairs overriding the defaults, e.g.
/// "left=outA,right=outD" or "touch=in2,ultrasonic=in1,colour=in4". Roles: left, right (output
/// ports outA..outD), touch, colour (or color), ultrasonic (input ports in1..in4). Every port is
/// used by one role at most. Returns false with @p why on the first problem; @p map is then unchanged.
constexpr bool parse_ports(std::string_view spec, PortMap& map, ReasonText& why) noexcept {
  PortMap m = map;
  why.clear();
  while (!spec.empty()) {
    const std::size_t comma = spec.find(',');
    const std::string_view item = spec.substr(0, comma);
    spec = comma == std::string_view::npos ? std::string_view{} : spec.substr(comma + 1);
    const std::size_t eq = item.find('=');
    if (eq == std::string_view::npos) {
      why.append("expected role=port, got ");
      append_quoted(why, item);
      return false;
    }
    std::string_view role = item.substr(0, eq);
    const std::string_view port = item.substr(eq + 1);
    if (role == "color") role = "colour";
    std::size_t r = kRoleCount;
    for (std::size_t i = 0; i < kRoleCount; ++i)
      if (to_string(static_cast<Role>(i)) == role) r = i;
    if (r == kRoleCount) {
      why.append("unknown role ");
      append_quoted(why, role);
      why.append(" (left, right, touch, colour, ultrasonic)");
      return false;
    }
    Dev d{};
    if (!parse_port(port, d)) {
      why.append("unknown port ");
      append_quoted(why, port);
      why.append(" (outA..outD, in1..in4)");
      return false;
    }
    const bool motor = r == static_cast<std::size_t>(Role::left) || r == static_cast<std::size_t>(Role::right);
    if (motor != is_out_port(d)) {
      why.append(role).append(motor ? " needs an output port (outA..outD), not " : " needs an input port (in1..in4), not ")
          .append(port);
      return false;
    }
    m.port[r] = d;
  }
  for (std::size_t i = 0; i < kRoleCount; ++i)
    for (std::size_t j = i + 1; j < kRoleCount; ++j)
      if (m.port[i] == m.port[j]) {
        why.append(to_string(m.port[i])).append(" given to both ").append(to_string(static_cast<Role>(i)))
            .append(" and ").append(to_string(static_cast<Role>(j)));
        return false;
      }
  map = m;
  return true;
}

/// The drive base. Defaults: model A built from the EV3 education core set (45544): its 56 x 28
/// tyre is 56 mm across (LEGO names tyres by diameter x width), and its driving base has about
/// 120 mm between the middles of the two tyres (a figure for the set's driving base, not measured
/// here; measure yours and pass it: a turn's error scales with it).
struct Geometry {
  double wheel_diameter_mm = 56.0;
  double wheel_base_mm = 120.0;
};

inline constexpr double kPi = 3.14159265358979323846;

/// The arc (mm) a wheel of @p g rolls for one count of a motor of @p count_per_rot counts a turn.
constexpr double mm_per_count(const Geometry& g, double count_per_rot) noexcept {
  return kPi * g.wheel_diameter_mm / count_per_rot;
}

}  // namespace ev3proto::robot
