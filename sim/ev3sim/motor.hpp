/// @file motor.hpp
/// @brief Emulation of one ev3dev tacho motor (tacho-motor class + legoev3-motor driver): its
///        attributes with the driver's checks and errors, its commands with their traps, and the
///        wheel it turns (position and speed in tacho counts, one count per degree).
///
/// The traps, as the driver has them (docs/devices.md, "Driver emulation"):
/// - setpoints (speed_sp, position_sp, time_sp, stop_action, polarity, ramps) are copied when a
///   command is written; writing a setpoint while running changes nothing until the next command
///   (duty_cycle_sp under run-direct is the one exception);
/// - `stop` with stop_action `hold` after a run-to-*-pos command holds at the position target, so
///   the motor keeps driving to position_sp;
/// - writing `position` fails with EBUSY while the motor runs or holds;
/// - a second run-to-rel-pos counts from the previous target, not from where the wheel is;
/// - a run-to-*-pos with speed_sp 0 never moves and never ends;
/// - stop_action must be one of stop_actions, command one of commands (else EINVAL); speed_sp
///   beyond max_speed, duty_cycle_sp beyond +-100, ramps outside 0..60000 ms: EINVAL.
///
/// Wheel dynamics (a model, docs/devices.md "Physics"): while powered the speed follows its
/// target with MotorDef::accel; a run-to-*-pos ends when the target is passed; stopping with
/// `coast` or `brake` removes power and the wheel slows by friction plus back-EMF (brake shorts
/// the windings: twice the coast's speed-proportional term); `hold` brakes hard with a position
/// loop (gain scaled by hold_pid/Kp) and holds.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "ev3sim/drivers.hpp"
#include "ev3sim/tree.hpp"

namespace ev3sim {

enum class StopAction { Coast, Brake, Hold };
enum class MotorCommand { None, RunForever, RunToAbsPos, RunToRelPos, RunTimed, RunDirect, Stop, Reset };

/// Stop dynamics of a wheel (per wheel degree): deceleration = a0 + k * |speed|.
struct StopModel {
  double a0;  ///< deg/s^2 (dry friction)
  double k;   ///< 1/s (viscous friction, back-EMF)
};
/// Coast: gearbox friction only; brake: windings shorted. Chosen so model A's coast slides
/// 1-5 cm from 25-100 % of max_speed (the thesis' figures); see docs/devices.md.
inline constexpr StopModel kCoast{409.0, 9.0};
inline constexpr StopModel kBrake{409.0, 18.0};
/// Hold: the position loop's strongest deceleration (deg/s^2) and its gains at hold_pid/Kp 80000.
inline constexpr double kHoldAccel = 20000.0;
inline constexpr double kHoldKp = 1600.0;  // 1/s^2
inline constexpr double kHoldKd = 80.0;    // 1/s
/// Speed reachable at full supply: max_speed at kNominalVolts and above, proportionally less
/// below (a drained battery makes the motor `overloaded` at high speed_sp).
inline constexpr double kNominalVolts = 7.5;
/// A motor driven against an obstacle this long reports `stalled`.
inline constexpr SimTime kStallUs = 100000;

class TachoMotor {
 public:
  explicit TachoMotor(const MotorDef& def);

  const MotorDef& def() const { return *def_; }

  /// Reads attribute @p name (address, driver_name, uevent and the power/ files are served by the
  /// tree builder, not here).
  ReadResult read(std::string_view name) const;
  /// Writes attribute @p name at simulated time @p now.
  WriteResult write(std::string_view name, std::string_view data, SimTime now);

  /// Advances the controller by @p dt seconds with the battery at @p volts; returns the wheel
  /// turn it drives this step, in counts of the user frame (polarity applied).
  double propose(double dt, double volts, SimTime now);
  /// Applies the step: the wheel turned @p delta counts; @p blocked when an obstacle stopped the
  /// robot (the wheel stalls: its speed drops to 0).
  void commit(double delta, bool blocked, SimTime now);
  /// +1, or -1 with polarity `inversed` (the physical sense of positive counts).
  double polarity_sign() const { return active_.inversed ? -1.0 : 1.0; }
  /// Current drawn from the battery (A).
  double current() const;

  // Observers (status, tests).
  long long position() const;
  double speed() const { return rate_; }
  std::string state() const;
  bool powered() const { return drive_ != Drive::Off; }

 private:
  enum class Drive { Off, Speed, ToPosition, Direct, Hold };
  struct Params {
    int speed_sp = 0;
    long long position_sp = 0;
    int time_sp = 0;
    int duty_cycle_sp = 0;
    int ramp_up_sp = 0;
    int ramp_down_sp = 0;
    StopAction stop_action = StopAction::Coast;
    bool inversed = false;
  };

  int send(MotorCommand cmd, SimTime now);
  void stop_with(StopAction a, bool after_position_command);
  void reset();
  double speed_cap(double volts) const;
  double approach(double target, double accel, double dt) const;

  const MotorDef* def_;
  Params params_;   // what the attributes say
  Params active_;   // copied at the last command
  int speed_pid_[3];
  int hold_pid_[3];
  MotorCommand command_ = MotorCommand::None;  // the last command written

  Drive drive_ = Drive::Off;
  StopModel off_model_ = kCoast;
  double pos_ = 0;         // counts, user frame
  double rate_ = 0;        // counts/s, user frame
  double ramp_sp_ = 0;     // the ramped speed setpoint
  double target_ = 0;      // position target (ToPosition) or hold point (Hold)
  double dir_ = 1;         // sense of travel to the target
  SimTime timed_end_ = 0;  // run-timed: when to stop (0: none)
  bool stopping_ = false;  // ramping down before stop_action (ramp_down_sp)
  bool ramping_ = false;
  bool overloaded_ = false;
  bool stalled_ = false;
  SimTime blocked_since_ = -1;
  double last_volts_ = kNominalVolts;
};

/// Parses a stop action name ("coast\n" too); false when unknown.
bool parse_stop_action(std::string_view s, StopAction& out);
const char* stop_action_name(StopAction a);

}  // namespace ev3sim
