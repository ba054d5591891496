#include "ev3sim/motor.hpp"

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>

namespace ev3sim {

namespace {

struct CommandName {
  MotorCommand cmd;
  const char* name;
};
// The driver's order (the `commands` attribute lists them so).
constexpr CommandName kCommands[] = {
    {MotorCommand::RunForever, "run-forever"}, {MotorCommand::RunToAbsPos, "run-to-abs-pos"},
    {MotorCommand::RunToRelPos, "run-to-rel-pos"}, {MotorCommand::RunTimed, "run-timed"},
    {MotorCommand::RunDirect, "run-direct"}, {MotorCommand::Stop, "stop"},
    {MotorCommand::Reset, "reset"},
};

std::string line(long long v) { return std::to_string(v) + "\n"; }

bool is_position_command(MotorCommand c) {
  return c == MotorCommand::RunToAbsPos || c == MotorCommand::RunToRelPos;
}

double sign(double v) { return v < 0 ? -1.0 : 1.0; }

}  // namespace

bool parse_stop_action(std::string_view s, StopAction& out) {
  for (StopAction a : {StopAction::Coast, StopAction::Brake, StopAction::Hold})
    if (sysfs_streq(s, stop_action_name(a))) {
      out = a;
      return true;
    }
  return false;
}

const char* stop_action_name(StopAction a) {
  switch (a) {
    case StopAction::Coast: return "coast";
    case StopAction::Brake: return "brake";
    case StopAction::Hold: return "hold";
  }
  return "coast";
}

TachoMotor::TachoMotor(const MotorDef& def) : def_(&def) {
  std::copy(def.speed_pid, def.speed_pid + 3, speed_pid_);
  std::copy(def.hold_pid, def.hold_pid + 3, hold_pid_);
}

long long TachoMotor::position() const { return std::llround(pos_); }

std::string TachoMotor::state() const {
  const bool running = drive_ == Drive::Speed || drive_ == Drive::ToPosition || drive_ == Drive::Direct;
  std::string s;
  auto flag = [&s](const char* f) {
    if (!s.empty()) s += ' ';
    s += f;
  };
  if (running) flag("running");
  if (running && ramping_) flag("ramping");
  if (drive_ == Drive::Hold) flag("holding");
  if (running && overloaded_) flag("overloaded");
  if (running && stalled_) flag("stalled");
  return s;
}

double TachoMotor::speed_cap(double volts) const {
  return def_->max_speed * std::min(1.0, std::max(0.0, volts) / kNominalVolts);
}

ReadResult TachoMotor::read(std::string_view name) const {
  if (name == "position") return {0, line(position())};
  if (name == "speed") return {0, line(std::llround(rate_))};
  if (name == "state") return {0, state() + "\n"};
  if (name == "duty_cycle") {
    double duty = 0;
    switch (drive_) {
      case Drive::Off: break;
      case Drive::Direct: duty = active_.duty_cycle_sp; break;
      case Drive::Hold: duty = hold_pid_[0] * (target_ - pos_) / 10000.0; break;
      case Drive::Speed:
      case Drive::ToPosition:
        duty = stalled_ ? 100.0 * sign(rate_ == 0 ? dir_ : rate_)
                        : 100.0 * rate_ / std::max(1.0, speed_cap(last_volts_));
        break;
    }
    return {0, line(std::llround(std::clamp(duty, -100.0, 100.0)))};
  }
  if (name == "count_per_rot") return {0, line(def_->count_per_rot)};
  if (name == "max_speed") return {0, line(def_->max_speed)};
  if (name == "commands") {
    std::string s;
    for (const CommandName& c : kCommands) s += std::string(s.empty() ? "" : " ") + c.name;
    return {0, s + "\n"};
  }
  if (name == "stop_actions") return {0, "coast brake hold\n"};
  if (name == "speed_sp") return {0, line(params_.speed_sp)};
  if (name == "position_sp") return {0, line(params_.position_sp)};
  if (name == "time_sp") return {0, line(params_.time_sp)};
  if (name == "duty_cycle_sp") return {0, line(params_.duty_cycle_sp)};
  if (name == "ramp_up_sp") return {0, line(params_.ramp_up_sp)};
  if (name == "ramp_down_sp") return {0, line(params_.ramp_down_sp)};
  if (name == "stop_action") return {0, std::string(stop_action_name(params_.stop_action)) + "\n"};
  if (name == "polarity") return {0, params_.inversed ? "inversed\n" : "normal\n"};
  static const char* const kPid[] = {"Kp", "Ki", "Kd"};
  for (int i = 0; i < 3; ++i) {
    if (name == std::string("speed_pid/") + kPid[i]) return {0, line(speed_pid_[i])};
    if (name == std::string("hold_pid/") + kPid[i]) return {0, line(hold_pid_[i])};
  }
  return {EACCES, {}};
}

WriteResult TachoMotor::write(std::string_view name, std::string_view data, SimTime now) {
  long long v = 0;
  auto parse = [&](long long lo, long long hi) { return parse_kernel_int(data, lo, hi, v); };
  if (name == "command") {
    for (const CommandName& c : kCommands)
      if (sysfs_streq(data, c.name)) return {send(c.cmd, now), 0};
    return {EINVAL, 0};
  }
  if (name == "speed_sp") {
    if (int e = parse(INT_MIN, INT_MAX)) return {e, 0};
    if (std::llabs(v) > def_->max_speed) return {EINVAL, 0};
    params_.speed_sp = static_cast<int>(v);
    return {};
  }
  if (name == "position_sp") {
    if (int e = parse(INT_MIN, INT_MAX)) return {e, 0};  // a long on the EV3 (32-bit ARM)
    params_.position_sp = v;
    return {};
  }
  if (name == "time_sp") {
    if (int e = parse(INT_MIN, INT_MAX)) return {e, 0};
    if (v < 0) return {EINVAL, 0};
    params_.time_sp = static_cast<int>(v);
    return {};
  }
  if (name == "duty_cycle_sp") {
    if (int e = parse(INT_MIN, INT_MAX)) return {e, 0};
    if (v < -100 || v > 100) return {EINVAL, 0};
    params_.duty_cycle_sp = static_cast<int>(v);
    if (command_ == MotorCommand::RunDirect) active_.duty_cycle_sp = params_.duty_cycle_sp;
    return {};
  }
  if (name == "ramp_up_sp" || name == "ramp_down_sp") {
    if (int e = parse(INT_MIN, INT_MAX)) return {e, 0};
    if (v < 0 || v > 60000) return {EINVAL, 0};
    (name == "ramp_up_sp" ? params_.ramp_up_sp : params_.ramp_down_sp) = static_cast<int>(v);
    return {};
  }
  if (name == "stop_action") {
    StopAction a;
    if (!parse_stop_action(data, a)) return {EINVAL, 0};
    params_.stop_action = a;
    return {};
  }
  if (name == "polarity") {
    if (sysfs_streq(data, "normal")) params_.inversed = false;
    else if (sysfs_streq(data, "inversed")) params_.inversed = true;
    else return {EINVAL, 0};
    return {};
  }
  if (name == "position") {
    if (int e = parse(INT_MIN, INT_MAX)) return {e, 0};
    if (drive_ != Drive::Off) return {EBUSY, 0};
    pos_ = static_cast<double>(v);
    return {};
  }
  static const char* const kPid[] = {"Kp", "Ki", "Kd"};
  for (int i = 0; i < 3; ++i) {
    const bool speed = name == std::string("speed_pid/") + kPid[i];
    if (speed || name == std::string("hold_pid/") + kPid[i]) {
      if (int e = parse(INT_MIN, INT_MAX)) return {e, 0};
      if (v < 0) return {EINVAL, 0};
      (speed ? speed_pid_ : hold_pid_)[i] = static_cast<int>(v);
      return {};
    }
  }
  return {EACCES, 0};
}

void TachoMotor::reset() {
  params_ = Params{};
  std::copy(def_->speed_pid, def_->speed_pid + 3, speed_pid_);
  std::copy(def_->hold_pid, def_->hold_pid + 3, hold_pid_);
  pos_ = 0;
  drive_ = Drive::Off;
  off_model_ = kCoast;
}

void TachoMotor::stop_with(StopAction a, bool after_position_command) {
  stopping_ = false;
  ramping_ = false;
  overloaded_ = false;
  stalled_ = false;
  timed_end_ = 0;
  switch (a) {
    case StopAction::Coast:
      drive_ = Drive::Off;
      off_model_ = kCoast;
      break;
    case StopAction::Brake:
      drive_ = Drive::Off;
      off_model_ = kBrake;
      break;
    case StopAction::Hold:
      // The driver's hold point after a position command is the position target.
      if (!after_position_command) target_ = pos_;
      drive_ = Drive::Hold;
      break;
  }
}

int TachoMotor::send(MotorCommand cmd, SimTime now) {
  const MotorCommand previous = command_;
  const double previous_target = target_;
  stopping_ = false;
  ramping_ = false;
  timed_end_ = 0;
  if (cmd == MotorCommand::Reset) {
    reset();
    active_ = params_;
    command_ = cmd;
    return 0;
  }
  if (params_.inversed != active_.inversed) rate_ = -rate_;  // the wheel keeps turning as it did
  active_ = params_;
  command_ = cmd;
  const bool ramps = active_.ramp_up_sp > 0 || active_.ramp_down_sp > 0;
  switch (cmd) {
    case MotorCommand::RunForever:
    case MotorCommand::RunTimed:
      drive_ = Drive::Speed;
      ramp_sp_ = ramps ? rate_ : active_.speed_sp;
      if (cmd == MotorCommand::RunTimed) timed_end_ = now + static_cast<SimTime>(active_.time_sp) * 1000;
      break;
    case MotorCommand::RunToAbsPos:
    case MotorCommand::RunToRelPos:
      if (cmd == MotorCommand::RunToAbsPos) target_ = static_cast<double>(active_.position_sp);
      else if (previous == MotorCommand::RunToRelPos) target_ = previous_target + static_cast<double>(active_.position_sp);
      else target_ = std::round(pos_) + static_cast<double>(active_.position_sp);
      dir_ = target_ >= pos_ ? 1.0 : -1.0;
      ramp_sp_ = std::fabs(rate_);
      drive_ = Drive::ToPosition;
      if (std::fabs(target_ - pos_) < 0.5) stop_with(active_.stop_action, true);
      break;
    case MotorCommand::RunDirect:
      drive_ = Drive::Direct;
      break;
    case MotorCommand::Stop:
      if (ramps && (drive_ == Drive::Speed || drive_ == Drive::ToPosition || drive_ == Drive::Direct)) {
        // The class ramps the speed down to zero first, then applies stop_action.
        drive_ = Drive::Speed;
        ramp_sp_ = rate_;
        stopping_ = true;
      } else {
        stop_with(active_.stop_action, is_position_command(previous));
      }
      break;
    case MotorCommand::None:
    case MotorCommand::Reset:
      break;
  }
  return 0;
}

double TachoMotor::approach(double target, double accel, double dt) const {
  const double step = accel * dt;
  if (std::fabs(target - rate_) <= step) return target;
  return rate_ + (target > rate_ ? step : -step);
}

double TachoMotor::propose(double dt, double volts, SimTime now) {
  last_volts_ = volts;
  const double cap = speed_cap(volts);
  if (drive_ == Drive::Speed && timed_end_ != 0 && now >= timed_end_) {
    timed_end_ = 0;
    if (active_.ramp_down_sp > 0) {
      stopping_ = true;
      ramp_sp_ = rate_;
    } else {
      stop_with(active_.stop_action, false);
    }
  }
  const double max = def_->max_speed;
  auto ramp_towards = [&](double target) {
    // ramp_up_sp / ramp_down_sp: ms to go from 0 to max_speed (0: at once).
    const bool up = std::fabs(target) > std::fabs(ramp_sp_) && target * ramp_sp_ >= 0;
    const int ms = up ? active_.ramp_up_sp : active_.ramp_down_sp;
    if (ms == 0) {
      ramp_sp_ = target;
    } else {
      const double step = max / (ms / 1000.0) * dt;
      ramp_sp_ = std::fabs(target - ramp_sp_) <= step ? target : ramp_sp_ + (target > ramp_sp_ ? step : -step);
    }
    ramping_ = ramp_sp_ != target;
  };
  switch (drive_) {
    case Drive::Speed: {
      const double target = stopping_ ? 0.0 : active_.speed_sp;
      if (active_.ramp_up_sp > 0 || active_.ramp_down_sp > 0) ramp_towards(target);
      else ramp_sp_ = target, ramping_ = false;
      if (stopping_) ramping_ = true;
      overloaded_ = std::fabs(ramp_sp_) > cap + 0.5;
      rate_ = approach(std::clamp(ramp_sp_, -cap, cap), def_->accel, dt);
      if (stopping_ && ramp_sp_ == 0.0) {
        stop_with(active_.stop_action, false);
      }
      break;
    }
    case Drive::ToPosition: {
      double allow = std::abs(active_.speed_sp);
      const double remaining = std::max(0.0, (target_ - pos_) * dir_);
      bool ramp = false;
      if (active_.ramp_down_sp > 0) {
        const double a = max / (active_.ramp_down_sp / 1000.0);
        const double v = std::max(std::sqrt(2 * a * remaining), std::min(allow, 30.0));
        if (v < allow) allow = v, ramp = true;
      }
      if (active_.ramp_up_sp > 0) {
        ramp_sp_ = std::min(allow, ramp_sp_ + max / (active_.ramp_up_sp / 1000.0) * dt);
        if (ramp_sp_ < allow) allow = ramp_sp_, ramp = true;
      }
      ramping_ = ramp;
      overloaded_ = allow > cap + 0.5;
      rate_ = approach(dir_ * std::min(allow, cap), def_->accel, dt);
      break;
    }
    case Drive::Direct: {
      const double target = active_.duty_cycle_sp / 100.0 * max * std::max(0.0, volts) / kNominalVolts;
      overloaded_ = false;
      ramping_ = false;
      rate_ = approach(target, def_->accel, dt);
      break;
    }
    case Drive::Hold: {
      const double kp = def_->hold_pid[0] > 0 ? kHoldKp * hold_pid_[0] / def_->hold_pid[0] : 0.0;
      double acc = kp * (target_ - pos_) - kHoldKd * rate_;
      if (kp == 0.0) acc = -(kCoast.a0 + kCoast.k * std::fabs(rate_)) * sign(rate_);
      acc = std::clamp(acc, -kHoldAccel, kHoldAccel);
      rate_ = std::clamp(rate_ + acc * dt, -cap, cap);
      break;
    }
    case Drive::Off: {
      const double dec = (off_model_.a0 + off_model_.k * std::fabs(rate_)) * dt;
      rate_ = std::fabs(rate_) <= dec ? 0.0 : rate_ - sign(rate_) * dec;
      break;
    }
  }
  return rate_ * dt;
}

void TachoMotor::commit(double delta, bool blocked, SimTime now) {
  pos_ += delta;
  if (blocked) {
    rate_ = 0;
    if (drive_ == Drive::Speed || drive_ == Drive::ToPosition || drive_ == Drive::Direct) {
      if (blocked_since_ < 0) blocked_since_ = now;
      stalled_ = now - blocked_since_ >= kStallUs;
    }
  } else {
    blocked_since_ = -1;
    stalled_ = false;
  }
  if (drive_ == Drive::ToPosition && (pos_ - target_) * dir_ >= 0) {
    stop_with(active_.stop_action, true);
  }
}

double TachoMotor::current() const {
  switch (drive_) {
    case Drive::Off: return 0.0;
    case Drive::Hold: return 0.08 + 0.6 * std::min(1.0, std::fabs(target_ - pos_) / 20.0);
    default: return 0.08 + 0.6 * std::fabs(rate_) / def_->max_speed + (stalled_ ? 1.2 : 0.0);
  }
}

}  // namespace ev3sim
