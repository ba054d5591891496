// A test double of a brick's devices for the robot transcripts: ev3dev's drivers reduced to what
// the runtime can observe, read and written by (Dev, Attr) as texts, with errno on failure.
//
// Motors (the tacho-motor driver, kinematically, stepped every 1 ms): run-forever / run-timed at
// speed_sp; run-to-abs-pos / run-to-rel-pos at |speed_sp| until the target, then the stop action;
// stop with coast (slows at kCoast counts/s^2: long slide), brake (kBrake: short), hold (brake,
// then back to the held position at kHoldSpeed). The driver's traps are modelled: setpoints act
// only when a command is written; `stop` with `hold` after a run-to-*-pos holds position_sp (so it
// keeps driving there); writing `position` while running or holding is EBUSY; a speed_sp beyond
// max_speed, a command or stop action not listed, a mode not listed are EINVAL; a run-to-rel-pos
// after a run-to-rel-pos counts from the previous target (legoev3_motor.c). No ramping, no
// slip: an ideal motor. It is no substitute for ev3-sim (sim/), which models the robot in a world.
#pragma once

#include <cerrno>
#include <cmath>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <tuple>
#include <map>
#include <string>
#include <vector>

#include "ev3proto/robot/device.hpp"

namespace ev3test {

using ev3proto::Millis;
using namespace ev3proto::robot;

/// Deceleration of a coasting / braking motor (counts/s^2) and the hold correction speed.
inline constexpr double kCoast = 4000, kBrake = 20000, kHoldSpeed = 100;

struct SimMotor {
  Driver driver = Driver::ev3_large_motor;
  int max_speed = 1050, count_per_rot = 360;
  std::string commands = "run-forever run-to-abs-pos run-to-rel-pos run-timed run-direct stop reset";
  std::string stop_actions = "coast brake hold";
  // attributes
  int speed_sp = 0, position_sp = 0, time_sp = 0;
  std::string stop_action = "coast";
  // motion
  enum class Mode { idle, forever, to_pos, timed, slowing, holding } mode = Mode::idle;
  double pos = 0, vel = 0, target = 0, decel = 0;
  Millis until = 0;
  std::string last_command = "reset";
  std::string slow_then = "coast";  // after slowing: coast (idle) or hold (holding)

  std::string state() const {
    switch (mode) {
      case Mode::forever:
      case Mode::to_pos:
      case Mode::timed: return "running";
      case Mode::holding: return "holding";
      default: return "";
    }
  }
  bool listed(const std::string& list, const std::string& w) const {
    return (" " + list + " ").find(" " + w + " ") != std::string::npos;
  }
  /// Stops with stop action @p a from the current motion.
  void stop_with(const std::string& a) {
    const bool after_pos = last_command == "run-to-abs-pos" || last_command == "run-to-rel-pos";
    if (a == "hold" && after_pos) {  // the trap: hold goes on driving to position_sp
      target = position_sp_target;
      hold_speed = std::max<double>(kHoldSpeed, std::abs(speed_sp));
      mode = Mode::holding;
    } else if (a == "hold") {
      target = pos;
      hold_speed = kHoldSpeed;
      mode = Mode::slowing;
      decel = kBrake;
      slow_then = "hold";
    } else {
      mode = Mode::slowing;
      decel = a == "coast" ? kCoast : kBrake;
      slow_then = "coast";
    }
  }
  double position_sp_target = 0;  // the absolute target of the last run-to-*-pos
  double hold_speed = kHoldSpeed;  // how fast holding corrects towards its target

  int command(const std::string& c, Millis now) {
    if (!listed(commands, c)) return EINVAL;
    if (c == "run-forever") {
      mode = Mode::forever;
      vel = speed_sp;
    } else if (c == "run-to-abs-pos" || c == "run-to-rel-pos") {
      // The driver's trap: a run-to-rel-pos after a run-to-rel-pos counts from the previous target.
      if (c == "run-to-abs-pos")
        target = position_sp;
      else if (last_command == "run-to-rel-pos")
        target = position_sp_target + position_sp;
      else
        target = static_cast<double>(std::llround(pos) + position_sp);
      position_sp_target = target;
      mode = Mode::to_pos;
      vel = (target >= pos ? 1 : -1) * std::abs(speed_sp);
    } else if (c == "run-timed") {
      mode = Mode::timed;
      vel = speed_sp;
      until = now + static_cast<Millis>(time_sp);
    } else if (c == "stop") {
      stop_with(stop_action);
    } else if (c == "reset") {
      *this = SimMotor{driver, max_speed, count_per_rot, commands, stop_actions};
      return 0;
    }
    last_command = c;
    return 0;
  }

  bool blocked = false;  // the wheel held fast (against a wall): it does not turn

  /// One millisecond of motion.
  void step(Millis now) {
    const double dt = blocked ? 0.0 : 0.001;
    switch (mode) {
      case Mode::idle: vel = 0; break;
      case Mode::forever: pos += vel * dt; break;
      case Mode::timed:
        pos += vel * dt;
        if (now >= until) stop_with(stop_action);
        break;
      case Mode::to_pos: {
        const double next = pos + vel * dt;
        if ((vel > 0 && next >= target) || (vel < 0 && next <= target) || vel == 0) {
          pos = next;
          stop_with(stop_action);
        } else {
          pos = next;
        }
        break;
      }
      case Mode::slowing: {
        pos += vel * dt;
        const double dv = decel * dt;
        if (std::abs(vel) <= dv) {
          vel = 0;
          mode = slow_then == "hold" ? Mode::holding : Mode::idle;
        } else {
          vel -= vel > 0 ? dv : -dv;
        }
        break;
      }
      case Mode::holding: {
        const double err = target - pos;
        const double d = std::min(std::abs(err), hold_speed * dt);
        pos += err > 0 ? d : -d;
        vel = 0;
        break;
      }
    }
  }

  std::string read(Attr a) const {
    switch (a) {
      case Attr::position: return std::to_string(std::llround(pos));
      case Attr::speed: return std::to_string(std::llround(vel));
      case Attr::state: return state();
      case Attr::speed_sp: return std::to_string(speed_sp);
      case Attr::position_sp: return std::to_string(position_sp);
      case Attr::stop_action: return stop_action;
      default: return "";
    }
  }
  int write(Attr a, const std::string& v, Millis now) {
    auto num = [&v](int& out) {
      char* end = nullptr;
      const long x = std::strtol(v.c_str(), &end, 10);
      if (v.empty() || *end != '\0') return false;
      out = static_cast<int>(x);
      return true;
    };
    int x = 0;
    switch (a) {
      case Attr::command: return command(v, now);
      case Attr::speed_sp:
        if (!num(x) || x > max_speed || x < -max_speed) return EINVAL;
        speed_sp = x;
        return 0;
      case Attr::position_sp:
        if (!num(x)) return EINVAL;
        position_sp = x;
        return 0;
      case Attr::time_sp:
        if (!num(x) || x < 0) return EINVAL;
        time_sp = x;
        return 0;
      case Attr::stop_action:
        if (!listed(stop_actions, v)) return EINVAL;
        stop_action = v;
        return 0;
      case Attr::position:
        if (mode != Mode::idle) return EBUSY;
        if (!num(x)) return EINVAL;
        pos = x;
        return 0;
      default: return EACCES;
    }
  }
};

/// A sensor: its modes with (decimals, units), its values as texts (garbage allowed).
struct SimSensor {
  Driver driver = Driver::ev3_touch;
  struct Mode {
    std::string name;
    int decimals;
    int num_values;
    std::string units;
  };
  std::vector<Mode> modes;
  std::size_t mode = 0;
  std::vector<std::string> values = std::vector<std::string>(8, "0");
  std::vector<Millis> mode_writes;  // when the mode was written

  static SimSensor of(Driver d) {
    SimSensor s;
    s.driver = d;
    switch (d) {
      case Driver::ev3_ultrasonic:
        s.modes = {{"US-DIST-CM", 1, 1, "cm"}, {"US-DIST-IN", 1, 1, "in"}, {"US-LISTEN", 0, 1, ""},
                   {"US-SI-CM", 1, 1, "cm"}, {"US-SI-IN", 1, 1, "in"}, {"US-DC-CM", 1, 1, "cm"},
                   {"US-DC-IN", 1, 1, "in"}};
        s.values[0] = "2550";
        break;
      case Driver::ev3_color:
        s.modes = {{"COL-REFLECT", 0, 1, "pct"}, {"COL-AMBIENT", 0, 1, "pct"}, {"COL-COLOR", 0, 1, "col"},
                   {"REF-RAW", 0, 2, ""}, {"RGB-RAW", 0, 3, ""}, {"COL-CAL", 0, 4, ""}};
        break;
      case Driver::ev3_gyro:
        s.modes = {{"GYRO-ANG", 0, 1, "deg"}, {"GYRO-RATE", 0, 1, "d/s"}, {"GYRO-FAS", 0, 1, ""},
                   {"GYRO-G&A", 0, 2, ""}, {"GYRO-CAL", 0, 4, ""}};
        break;
      default: s.modes = {{"TOUCH", 0, 1, ""}}; break;
    }
    return s;
  }
  std::string modes_text() const {
    std::string t;
    for (const auto& m : modes) t += (t.empty() ? "" : " ") + m.name;
    return t;
  }
  SensorInfo info() const {
    SensorTexts t;
    const std::string ml = modes_text(), d = std::to_string(modes[mode].decimals),
                      n = std::to_string(modes[mode].num_values);
    t.driver_name = to_string(driver);
    t.modes = ml;
    t.mode = modes[mode].name;
    t.decimals = d;
    t.num_values = n;
    t.units = modes[mode].units;
    SensorInfo out;
    ReasonText why;
    parse_sensor_info(t, out, why);
    return out;
  }
  std::string read(Attr a) const {
    if (a >= Attr::value0 && a <= Attr::value7)
      return values[static_cast<std::size_t>(a) - static_cast<std::size_t>(Attr::value0)];
    switch (a) {
      case Attr::mode: return modes[mode].name;
      case Attr::decimals: return std::to_string(modes[mode].decimals);
      case Attr::num_values: return std::to_string(modes[mode].num_values);
      case Attr::units: return modes[mode].units;
      default: return "";
    }
  }
  int write(Attr a, const std::string& v, Millis now) {
    if (a != Attr::mode) return EACCES;
    for (std::size_t i = 0; i < modes.size(); ++i)
      if (modes[i].name == v) {
        mode = i;
        mode_writes.push_back(now);
        return 0;
      }
    return EINVAL;
  }
};

/// The devices of one brick.
struct World {
  std::map<Dev, SimMotor> motors;
  std::map<Dev, SimSensor> sensors;
  std::map<Dev, std::map<Attr, std::string>> leds;
  std::string battery_uv = "8000000";
  bool battery = true;
  /// Injected faults: (dev, attr, 'r' or 'w') -> errno, used once each.
  std::map<std::tuple<Dev, Attr, char>, int> faults;

  void step(Millis now) {
    for (auto& [d, m] : motors) m.step(now);
  }
  bool present(Dev d) const {
    return motors.count(d) != 0 || sensors.count(d) != 0 || is_led(d) || (d == Dev::battery && battery);
  }
  /// Reads @p a of @p d into @p out; returns 0 or an errno (ENODEV: nothing there).
  int read(Dev d, Attr a, std::string& out) {
    if (take_fault(d, a, 'r', out)) return std::atoi(out.c_str());
    if (d == Dev::battery) {
      if (!battery) return ENODEV;
      out = battery_uv;
      return 0;
    }
    if (auto m = motors.find(d); m != motors.end()) {
      out = m->second.read(a);
      return 0;
    }
    if (auto s = sensors.find(d); s != sensors.end()) {
      out = s->second.read(a);
      return 0;
    }
    return ENODEV;
  }
  int write(Dev d, Attr a, const std::string& v, Millis now) {
    std::string e;
    if (take_fault(d, a, 'w', e)) return std::atoi(e.c_str());
    if (is_led(d)) {
      leds[d][a] = v;
      return 0;
    }
    if (auto m = motors.find(d); m != motors.end()) return m->second.write(a, v, now);
    if (auto s = sensors.find(d); s != sensors.end()) return s->second.write(a, v, now);
    return ENODEV;
  }

 private:
  bool take_fault(Dev d, Attr a, char rw, std::string& err) {
    auto f = faults.find({d, a, rw});
    if (f == faults.end()) return false;
    err = std::to_string(f->second);
    faults.erase(f);
    return true;
  }
};

}  // namespace ev3test
