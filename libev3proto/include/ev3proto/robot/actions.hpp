/// @file actions.hpp
/// @brief Actions (brief sec. 6, thesis 3.1.2): a sequence of commands, an end condition, and the
///        events that may interrupt it, as sans-I/O state machines. Inputs: the readings the
///        runtime took this tick (Body), events, time; outputs: device writes, sensor reports, and
///        an Outcome (running / finished / interrupted / failed) with a detail in words.
///
/// The actions of model A: DriveDistance, Turn, RunForever, Stop, Pause, Wait, and Repeat(n, ...)
/// over them (a Plan). ActionRunner runs one Plan; the Runtime owns it and the Body.
///
/// End conditions (positions only: one pread per wheel per tick):
/// - DriveDistance / Turn: the driver runs both wheels to their targets (run-to-abs-pos to the
///   position read this tick + the counts of the distance or angle); the action
///   ends when each wheel is at its target or beyond (short by at most reach_counts) and has stopped
///   (two readings after the command within still_counts). A wheel that makes no progress for
///   stall_ms short of its target fails the action ("outB stalled ..."), motors stopped.
/// - RunForever: never ends by itself; fails when a wheel stalls.
/// - Stop: ends when both wheels have stopped; fails when they still turn after stop_timeout_ms.
/// - Pause: stops the motors, ends once they are still and settle_ms has passed, reporting a clean
///   reading (taken after that) of each sensor it lists.
/// - Wait: ends after its time (no motors).
/// Every action fails when a reading it needs has been missing or garbage for stale_ms.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "../timers.hpp"
#include "command.hpp"
#include "device.hpp"
#include "events.hpp"
#include "model.hpp"
#include "../ring.hpp"
#include "text.hpp"

namespace ev3proto::robot {

/// The last two good position readings of one motor (the runtime fills it every tick).
struct MotorReadings {
  bool valid = false;  ///< at least one good reading since the motor appeared
  std::int32_t position = 0;
  Millis at = 0;
  bool has_prev = false;
  std::int32_t prev = 0;
  Millis prev_at = 0;

  void update(std::int32_t p, Millis now) noexcept {
    has_prev = valid;
    prev = position;
    prev_at = at;
    valid = true;
    position = p;
    at = now;
  }
  void clear() noexcept { *this = MotorReadings{}; }
};

/// The last good values of one sensor.
struct SensorReadings {
  bool valid = false;      ///< values[] hold a reading in the current mode
  bool info_stale = false; ///< the mode was written: decimals / num_values / units must be read again
  Fixed values[kMaxValues];
  std::uint8_t count = 0;  ///< values read (num_values of the mode)
  Millis at = 0;

  void clear() noexcept { *this = SensorReadings{}; }
};

/// Tuning of the end conditions (see the file comment).
struct MoveTuning {
  std::int32_t reach_counts = 5;  ///< a wheel this many counts short of its target has reached it
  std::int32_t still_counts = 1;  ///< a wheel that moved at most this much between two ticks is still
  Millis stall_ms = 1000;         ///< no progress this long short of the target: stalled
  Millis stop_timeout_ms = 3000;  ///< Stop / Pause: wheels still turning after this: failed
  Millis stale_ms = 500;          ///< a needed reading missing this long: failed
  StopAction pause_stop = StopAction::brake;  ///< how motors stop on pause / halt
};

/// What the actions act on and observe: the two drive motors, the four input ports' sensors, the
/// geometry. The Runtime owns it and keeps the readings current.
struct Body {
  Tacho left, right;
  MotorReadings left_pos, right_pos;
  Sensor sensors[4];           ///< in1..in4
  SensorReadings readings[4];  ///< in1..in4
  Geometry geo;
  MoveTuning tuning;

  Tacho& motor(std::size_t w) noexcept { return w == 0 ? left : right; }
  const Tacho& motor(std::size_t w) const noexcept { return w == 0 ? left : right; }
  MotorReadings& pos(std::size_t w) noexcept { return w == 0 ? left_pos : right_pos; }
  const MotorReadings& pos(std::size_t w) const noexcept { return w == 0 ? left_pos : right_pos; }
  static constexpr std::size_t in_index(Dev d) noexcept { return index(d) - index(Dev::in1); }
};

/// A sensor reading a Pause took after settling (agent core: sensor_report(port, mode, values)).
struct Report {
  bool odometry = false;  ///< the robot's pose (port `pose`, mode ODOM: x mm, y mm, heading degrees)
  Dev port = Dev::in1;
  ModeName mode;
  Fixed values[kMaxValues];
  std::uint8_t count = 0;
};
/// The port SENSOR_VALUE names for @p r: its sensor's port (`in4`), or `pose` for odometry.
constexpr std::string_view report_port(const Report& r) noexcept {
  return r.odometry ? std::string_view("pose") : to_string(r.port);
}

/// Reports waiting to be taken (full: the oldest is dropped and counted).
class Reports {
 public:
  void push(const Report& r) noexcept {
    if (ring_.push_over(r)) ++dropped_;
  }
  bool pop(Report& out) noexcept { return ring_.pop(out); }
  std::size_t dropped() const noexcept { return dropped_; }

 private:
  Ring<Report, 8> ring_;
  std::size_t dropped_ = 0;
};

/// What an action call gives back.
enum class Outcome : std::uint8_t { running, finished, interrupted, failed };

constexpr std::string_view to_string(Outcome o) noexcept {
  switch (o) {
    case Outcome::running: return "running";
    case Outcome::finished: return "finished";
    case Outcome::interrupted: return "interrupted";
    case Outcome::failed: return "failed";
  }
  return {};
}

/// The inputs and outputs of one action call.
struct Ctx {
  Body& body;
  Writes& writes;
  Reports& reports;
  Millis now;
  /// The motors may turn until then (the runtime's contact watchdog); ~0: no bound. A RunForever
  /// step under a bound is written as run-timed ending at it, so the motor driver stops the wheels
  /// there by itself even when the program stalls.
  Millis run_until = ~Millis{0};
};

namespace action {

/// The action kinds (the set is fixed per robot model, thesis 3.1.2).
enum class Kind : std::uint8_t { drive_distance, turn, run_forever, stop, pause, wait };

constexpr std::string_view to_string(Kind k) noexcept {
  switch (k) {
    case Kind::drive_distance: return "DriveDistance";
    case Kind::turn: return "Turn";
    case Kind::run_forever: return "RunForever";
    case Kind::stop: return "Stop";
    case Kind::pause: return "Pause";
    case Kind::wait: return "Wait";
  }
  return {};
}

/// The front-facing warnings: they interrupt motion forward (the bumper and the ultrasonic face
/// forward; backing away from an obstacle is not interrupted by it).
inline constexpr EventSet kForwardWarnings =
    event_bit(EventKind::OBSTACLE_DETECTED) | event_bit(EventKind::PROXIMITY_ALERT);

/// One action with its parameters (a value: Plans are lists of them).
struct Step {
  Kind kind = Kind::wait;
  std::int32_t mm = 0;       ///< DriveDistance: distance (negative: backwards)
  std::int32_t degrees = 0;  ///< Turn: angle (positive: counter-clockwise, to the left)
  std::int32_t speed = 0;    ///< counts/s (deg/s on EV3 motors); RunForever: left wheel
  std::int32_t speed_right = 0;  ///< RunForever: right wheel
  StopAction stop = StopAction::brake;  ///< how the motors stop at the end or on an interrupt
  Millis ms = 0;             ///< Wait: duration; Pause: settle time
  std::uint8_t sensors = 0;  ///< Pause: input ports to read after settling (bit i = in(i+1))
  EventSet interrupts = 0;   ///< events that interrupt it
};

/// DriveDistance: both wheels by @p mm at @p speed, then @p stop. Interrupted by the forward
/// warnings when driving forward.
constexpr Step drive_distance(std::int32_t mm, std::int32_t speed, StopAction stop = StopAction::brake) noexcept {
  Step s;
  s.kind = Kind::drive_distance;
  s.mm = mm;
  s.speed = speed < 0 ? -speed : speed;
  s.stop = stop;
  s.interrupts = mm > 0 ? kForwardWarnings : EventSet{0};
  return s;
}
/// Turn in place about the axle midpoint by @p degrees (positive: left), wheels opposite, at
/// @p speed (slow is more precise, thesis 6.1.1). Not interrupted by default.
constexpr Step turn(std::int32_t degrees, std::int32_t speed, StopAction stop = StopAction::brake) noexcept {
  Step s;
  s.kind = Kind::turn;
  s.degrees = degrees;
  s.speed = speed < 0 ? -speed : speed;
  s.stop = stop;
  return s;
}
/// RunForever at @p left / @p right speeds (negative: backwards) until interrupted or stopped;
/// interrupted by the forward warnings unless both wheels go backwards.
constexpr Step run_forever(std::int32_t left, std::int32_t right, StopAction stop = StopAction::brake) noexcept {
  Step s;
  s.kind = Kind::run_forever;
  s.speed = left;
  s.speed_right = right;
  s.stop = stop;
  s.interrupts = left > 0 || right > 0 ? kForwardWarnings : EventSet{0};
  return s;
}
/// Stop both motors with @p how and wait until they are still.
constexpr Step stop(StopAction how) noexcept {
  Step s;
  s.kind = Kind::stop;
  s.stop = how;
  return s;
}
/// Pause: stop (brake), let the robot settle for at least @p settle_ms, then report a clean reading
/// of each input port in @p sensor_ports (bit i = in(i+1)).
constexpr Step pause(Millis settle_ms, std::uint8_t sensor_ports = 0) noexcept {
  Step s;
  s.kind = Kind::pause;
  s.ms = settle_ms;
  s.sensors = sensor_ports;
  return s;
}
/// Wait @p ms with the motors untouched.
constexpr Step wait(Millis ms) noexcept {
  Step s;
  s.kind = Kind::wait;
  s.ms = ms;
  return s;
}

/// The most steps a Plan holds.
inline constexpr std::size_t kMaxSteps = 8;

/// Steps run in order, `times` times (Repeat(n, ...); 0 = until interrupted or stopped).
struct Plan {
  Step steps[kMaxSteps];
  std::uint8_t count = 0;
  std::uint16_t times = 1;
};

/// A plan of one action.
constexpr Plan single(const Step& s) noexcept {
  Plan p;
  p.steps[0] = s;
  p.count = 1;
  return p;
}
/// Repeat(n, steps...): @p steps (at most kMaxSteps) @p n times (0: forever).
template <std::size_t K>
constexpr Plan repeat(std::uint16_t n, const Step (&steps)[K]) noexcept {
  static_assert(K >= 1 && K <= kMaxSteps, "Repeat takes 1..kMaxSteps steps");
  Plan p;
  for (std::size_t i = 0; i < K; ++i) p.steps[i] = steps[i];
  p.count = static_cast<std::uint8_t>(K);
  p.times = n;
  return p;
}

}  // namespace action

/// Which readings the running action needs each tick.
struct Needs {
  bool motors = false;          ///< both wheels' position
  std::uint8_t sensor_ports = 0;  ///< values of these input ports (bit i = in(i+1))
};

/// Runs one Plan. Sans-I/O: every call takes a Ctx (body with this tick's readings, the write
/// queue, the report queue, now) and returns the Outcome; detail() says what happened in words.
class ActionRunner {
 public:
  /// Starts @p plan from its first step.
  Outcome start(const action::Plan& plan, Ctx& c) noexcept {
    plan_ = plan;
    index_ = 0;
    iteration_ = 0;
    detail_.clear();
    cause_ = EventKind::OBSTACLE_DETECTED;
    if (plan_.count == 0) return end(Outcome::finished);
    phase_ = Phase::running;
    ReasonText why;
    if (!check(plan_, c.body, why)) return fail(c, why, false);
    return start_step(c);
  }

  /// Checks every step of @p plan against the motors' limits before anything moves (a Repeat whose
  /// third step has a speed beyond max_speed is refused whole). Motors not there are not checked
  /// here (the step that needs them fails when it starts).
  static bool check(const action::Plan& plan, const Body& b, ReasonText& why) noexcept {
    for (std::size_t i = 0; i < plan.count; ++i) {
      const action::Step& s = plan.steps[i];
      for (std::size_t w = 0; w < 2; ++w) {
        Tacho m = b.motor(w);  // a copy: checking must not change what the real one remembers
        if (!m.present()) continue;
        Writes scratch;
        bool ok = true;
        switch (s.kind) {
          case action::Kind::drive_distance:
          case action::Kind::turn: ok = m.apply(RunToAbsPos{0, s.speed, s.stop}, scratch, why); break;
          case action::Kind::run_forever: ok = m.apply(RunForever{w == 0 ? s.speed : s.speed_right}, scratch, why); break;
          case action::Kind::stop:
          case action::Kind::pause: ok = m.apply(Stop{s.stop}, scratch, why); break;
          case action::Kind::wait: break;
        }
        if (!ok) return false;
      }
    }
    return true;
  }

  /// After this tick's readings: checks the end condition of the running step.
  Outcome tick(Ctx& c) noexcept {
    if (phase_ != Phase::running) return Outcome::running;
    if (waiting_) {  // the step waits for its first readings (a start right after discovery)
      ReasonText why;
      if (motors_ready(c, why)) return start_step(c);
      if (c.now - started_ >= c.body.tuning.stale_ms) return fail(c, why);
      return Outcome::running;
    }
    Outcome o = Outcome::running;
    switch (step().kind) {
      case action::Kind::drive_distance:
      case action::Kind::turn: o = tick_move(c); break;
      case action::Kind::run_forever: o = tick_forever(c); break;
      case action::Kind::stop: o = tick_stop(c); break;
      case action::Kind::pause: o = tick_pause(c); break;
      case action::Kind::wait:
        if (c.now < due_) break;
        o = Outcome::finished;
        detail_.clear();
        detail_.append("waited ").append_int(static_cast<std::int64_t>(step().ms)).append(" ms");
        break;
    }
    if (o == Outcome::finished) return next_step(c);
    if (o != Outcome::running) return end(o);
    return o;
  }

  /// An event: when the running step lists it, its motors stop (with the step's stop action) and
  /// the plan ends interrupted. Other events change nothing.
  Outcome event(const Event& e, Ctx& c) noexcept {
    if (phase_ != Phase::running || !contains(step().interrupts, e.kind)) return Outcome::running;
    const std::int32_t done = progress_tenths(c);
    stop_motors(c, step().stop);
    cause_ = e.kind;
    detail_.clear();
    detail_.append("interrupted by ").append(to_string(e.kind));
    if (is_port(e.dev)) detail_.append(" on ").append(to_string(e.dev));
    append_progress(done);
    return end(Outcome::interrupted);
  }

  /// The agent core paused (or the master is lost): motors stop at once, progress kept.
  void pause(Ctx& c) noexcept {
    if (phase_ != Phase::running) return;
    phase_ = Phase::paused;
    switch (step().kind) {
      case action::Kind::wait: left_ = due_ > c.now ? due_ - c.now : 0; break;
      default: stop_motors(c, c.body.tuning.pause_stop); break;
    }
  }

  /// Continue a paused plan where it was: a move goes on to the same targets (run-to-abs-pos).
  Outcome resume(Ctx& c) noexcept {
    if (phase_ != Phase::paused) return Outcome::running;
    phase_ = Phase::running;
    switch (step().kind) {
      case action::Kind::drive_distance:
      case action::Kind::turn: return resume_move(c);
      case action::Kind::wait: due_ = c.now + left_; return Outcome::running;
      default: return start_step(c);  // RunForever, Stop, Pause begin again
    }
  }

  /// Stop everything (agent core stop, a critical event): motors stopped with @p how, plan dropped.
  void halt(Ctx& c, StopAction how) noexcept {
    if (phase_ == Phase::idle) return;
    if (moves_motors()) stop_motors(c, how);
    phase_ = Phase::idle;
  }

  /// Forget the plan without touching the motors (the next plan commands them at once).
  void drop() noexcept { phase_ = Phase::idle; }

  bool active() const noexcept { return phase_ != Phase::idle; }
  bool paused() const noexcept { return phase_ == Phase::paused; }
  /// The running step (meaningful while active()).
  const action::Step& step() const noexcept { return plan_.steps[index_]; }
  /// True when the running step drives the motors (the runtime ticks fast then).
  bool moves_motors() const noexcept {
    return phase_ != Phase::idle && step().kind != action::Kind::wait;
  }
  /// True when the running step turns the wheels towards something (DriveDistance, Turn,
  /// RunForever): what the contact watchdog holds.
  bool turns_motors() const noexcept {
    if (phase_ != Phase::running || waiting_) return false;
    const action::Kind k = step().kind;
    return k == action::Kind::drive_distance || k == action::Kind::turn || k == action::Kind::run_forever;
  }
  /// When the watchdog's bound (c.run_until) moved on and less than half of the time to the bound
  /// written last is left, a running RunForever is written again as run-timed to the new bound;
  /// nothing else changes (its stall watch goes on). False when that
  /// write was refused: the plan failed then (detail() says why).
  bool renew(Ctx& c) noexcept {
    if (phase_ != Phase::running || waiting_ || step().kind != action::Kind::run_forever) return true;
    if (c.run_until == kNever || c.run_until <= bound_) return true;
    if (!c.body.left.can_run_timed() || !c.body.right.can_run_timed()) return true;  // run-forever: no bound
    // Written again once half the time to the bound written last is spent (not at every contact).
    if (bound_ > c.now && 2 * (bound_ - c.now) >= c.run_until - c.now) return true;
    ReasonText why;
    if (run_wheels(c, why)) return true;
    fail(c, why);
    return false;
  }
  /// The readings the running step needs.
  Needs needs() const noexcept {
    Needs n;
    if (phase_ != Phase::running) return n;
    n.motors = step().kind != action::Kind::wait;
    if (step().kind == action::Kind::pause) n.sensor_ports = step().sensors;
    return n;
  }
  /// When tick() must be called at the latest for time alone (Wait's end), else kNever.
  Millis deadline() const noexcept {
    return phase_ == Phase::running && step().kind == action::Kind::wait ? due_ : kNever;
  }
  /// What happened, in words ("drove 300.2 mm", "outB stalled at 120 of 614 counts").
  const ReasonText& detail() const noexcept { return detail_; }
  /// The event that interrupted the plan (after Outcome::interrupted).
  EventKind cause() const noexcept { return cause_; }

  static constexpr Millis kNever = ~Millis{0};

 private:
  enum class Phase : std::uint8_t { idle, running, paused };

  Outcome end(Outcome o) noexcept {
    phase_ = Phase::idle;
    return o;
  }

  /// Ends the plan failed; the motors are stopped unless nothing was commanded yet (@p stop false).
  Outcome fail(Ctx& c, const ReasonText& why, bool stop = true) noexcept {
    const ReasonText copy = why;  // why may be detail_ itself
    if (stop && moves_motors()) stop_motors(c, StopAction::brake);
    detail_ = copy;
    return end(Outcome::failed);
  }

  Outcome next_step(Ctx& c) noexcept {
    ++index_;
    if (index_ < plan_.count) return start_step(c);
    ++iteration_;
    if (plan_.times == 0 || iteration_ < plan_.times) {
      index_ = 0;
      return start_step(c);
    }
    if (plan_.count > 1 || plan_.times != 1) {
      detail_.clear();
      detail_.append("repeated ").append_int(iteration_).append(iteration_ == 1 ? " time" : " times");
    }
    return end(Outcome::finished);
  }

  Outcome start_step(Ctx& c) noexcept {
    const action::Step& s = step();
    detail_.clear();
    if (!waiting_) started_ = c.now;
    cmd_at_ = c.now;
    waiting_ = false;
    if (s.kind != action::Kind::wait && s.kind != action::Kind::pause) {
      ReasonText why;
      if (!motors_ready(c, why)) {
        bool absent = false;
        for (std::size_t w = 0; w < 2; ++w) absent = absent || !c.body.motor(w).present();
        if (absent) return fail(c, why);
        waiting_ = true;  // present but not read yet: start at the first tick that has positions
        return Outcome::running;
      }
    }
    switch (s.kind) {
      case action::Kind::drive_distance:
      case action::Kind::turn: return start_move(c);
      case action::Kind::run_forever: {
        ReasonText why;
        for (std::size_t w = 0; w < 2; ++w) {
          anchor_[w] = c.body.pos(w).position;
          progress_at_[w] = c.now;
        }
        if (!run_wheels(c, why)) return fail(c, why, false);
        return Outcome::running;
      }
      case action::Kind::stop: {
        ReasonText why;
        if (!motors_ready(c, why)) return fail(c, why);
        stop_motors(c, s.stop);
        return Outcome::running;
      }
      case action::Kind::pause: {
        for (std::size_t i = 0; i < 4; ++i)
          if ((s.sensors & (1u << i)) != 0 && !c.body.sensors[i].present()) {
            ReasonText why;
            why.append(to_string(static_cast<Dev>(index(Dev::in1) + i))).append(": no sensor on the port");
            return fail(c, why, false);
          }
        stop_motors(c, s.stop);
        return Outcome::running;
      }
      case action::Kind::wait:
        due_ = c.now + s.ms;
        return Outcome::running;
    }
    return Outcome::running;
  }

  /// The wheels at the RunForever step's speeds: run-forever, or, under the watchdog's bound,
  /// run-timed to that bound (a motor without run-timed gets run-forever).
  bool run_wheels(Ctx& c, ReasonText& why) noexcept {
    const action::Step& s = step();
    const bool timed = c.run_until != kNever && c.body.left.can_run_timed() && c.body.right.can_run_timed();
    bound_ = timed ? c.run_until : 0;  // 0: none written (renew() writes one once there is a bound)
    if (!timed) return both(c, RunForever{s.speed}, RunForever{s.speed_right}, why);
    const Millis left = c.run_until > c.now ? c.run_until - c.now : 0;
    const std::int32_t ms = left > 0x7fffffff ? 0x7fffffff : static_cast<std::int32_t>(left);
    const StopAction how = c.body.tuning.pause_stop;
    return both(c, RunTimed{ms, s.speed, how}, RunTimed{ms, s.speed_right, how}, why);
  }

  bool motors_ready(Ctx& c, ReasonText& why) const noexcept {
    for (std::size_t w = 0; w < 2; ++w) {
      const Tacho& m = c.body.motor(w);
      if (!m.present()) {
        why.clear();
        why.append(to_string(m.port())).append(": no motor on the port");
        return false;
      }
      if (!c.body.pos(w).valid) {
        why.clear();
        why.append(to_string(m.port())).append(": no position read yet");
        return false;
      }
    }
    return true;
  }

  /// Counts for @p mm of travel of wheel @p w (its own count_per_rot).
  static std::int32_t counts_for_mm(double mm, const Body& b, const Tacho& m) noexcept {
    return static_cast<std::int32_t>(std::lround(mm / mm_per_count(b.geo, m.info().count_per_rot)));
  }
  static double mm_for_counts(std::int64_t counts, const Body& b, const Tacho& m) noexcept {
    return static_cast<double>(counts) * mm_per_count(b.geo, m.info().count_per_rot);
  }
  /// @p v held within std::int32_t (a target beyond a motor's position range is at its end).
  static constexpr std::int32_t clamp32(std::int64_t v) noexcept {
    return static_cast<std::int32_t>(std::clamp<std::int64_t>(v, INT32_MIN, INT32_MAX));
  }

  Outcome start_move(Ctx& c) noexcept {
    const action::Step& s = step();
    ReasonText why;
    if (!motors_ready(c, why)) return fail(c, why);
    Body& b = c.body;
    for (std::size_t w = 0; w < 2; ++w) {
      double mm = s.mm;
      if (s.kind == action::Kind::turn) {  // each wheel on a circle of radius base/2 about the midpoint
        const double arc = s.degrees * kPi / 180.0 * b.geo.wheel_base_mm / 2.0;
        mm = w == 0 ? -arc : arc;
      }
      counts_[w] = counts_for_mm(mm, b, b.motor(w));
      start_pos_[w] = b.pos(w).position;
      target_[w] = clamp32(std::int64_t{start_pos_[w]} + counts_[w]);
      anchor_[w] = start_pos_[w];
      progress_at_[w] = c.now;
    }
    // run-to-abs-pos to the targets computed from this tick's positions: the driver's own target is
    // then exactly ours (run-to-rel-pos would count from the previous run-to-rel-pos's target).
    if (!both(c, RunToAbsPos{target_[0], s.speed, s.stop}, RunToAbsPos{target_[1], s.speed, s.stop}, why,
              counts_[0] != 0, counts_[1] != 0))
      return fail(c, why, false);
    return Outcome::running;
  }

  /// Commands the left wheel with @p l and the right with @p r (each only when @p use_l / @p use_r),
  /// or neither: when one is refused nothing is written and @p why says why.
  template <typename L, typename R>
  static bool both(Ctx& c, const L& l, const R& r, ReasonText& why, bool use_l = true, bool use_r = true) noexcept {
    Tacho left = c.body.left, right = c.body.right;
    Writes scratch;
    if ((use_l && !left.apply(l, scratch, why)) || (use_r && !right.apply(r, scratch, why))) return false;
    c.body.left = left;
    c.body.right = right;
    for (Write w; scratch.pop(w);) c.writes.push(w);
    return true;
  }

  Outcome resume_move(Ctx& c) noexcept {
    const action::Step& s = step();
    ReasonText why;
    if (!motors_ready(c, why)) return fail(c, why);
    cmd_at_ = c.now;
    for (std::size_t w = 0; w < 2; ++w) {
      progress_at_[w] = c.now;
      anchor_[w] = c.body.pos(w).position;
    }
    if (!both(c, RunToAbsPos{target_[0], s.speed, s.stop}, RunToAbsPos{target_[1], s.speed, s.stop}, why,
              !reached(0, c.body.left_pos.position, c.body.tuning), !reached(1, c.body.right_pos.position, c.body.tuning)))
      return fail(c, why);
    return Outcome::running;
  }

  bool reached(std::size_t w, std::int32_t pos, const MoveTuning& t) const noexcept {
    if (counts_[w] > 0) return pos >= std::int64_t{target_[w]} - t.reach_counts;
    if (counts_[w] < 0) return pos <= std::int64_t{target_[w]} + t.reach_counts;
    return true;
  }

  /// Every present wheel has a good reading younger than stale_ms; false (the plan failed, @p o
  /// says so) when one has none.
  bool fresh(Ctx& c, Outcome& o) noexcept {
    for (std::size_t w = 0; w < 2; ++w) {
      const MotorReadings& r = c.body.pos(w);
      if (!c.body.motor(w).present() || (r.valid && c.now - r.at < c.body.tuning.stale_ms)) continue;
      ReasonText why;
      why.append(to_string(c.body.motor(w).port())).append(": no good position for ");
      if (r.valid)
        why.append_int(static_cast<std::int64_t>(c.now - r.at)).append(" ms");
      else
        why.append("ever since it appeared");
      o = fail(c, why);
      return false;
    }
    return true;
  }

  /// Wheel @p w has not moved (more than still_counts) between its last two readings, both taken
  /// after the last command.
  bool still(const Ctx& c, std::size_t w) const noexcept {
    const MotorReadings& r = c.body.pos(w);
    const std::int64_t d = std::int64_t{r.position} - r.prev;  // any two readings: no overflow
    return r.valid && r.has_prev && r.prev_at > cmd_at_ && d <= c.body.tuning.still_counts &&
           -d <= c.body.tuning.still_counts;
  }

  /// Notes progress of wheel @p w; true when it has made none for stall_ms.
  bool stalled(const Ctx& c, std::size_t w) noexcept {
    const std::int32_t p = c.body.pos(w).position;
    const std::int64_t d = std::int64_t{p} - anchor_[w];
    if (d > c.body.tuning.still_counts || -d > c.body.tuning.still_counts) {
      anchor_[w] = p;
      progress_at_[w] = c.now;
      return false;
    }
    return c.now - progress_at_[w] >= c.body.tuning.stall_ms;
  }

  Outcome tick_move(Ctx& c) noexcept {
    Outcome o = Outcome::running;
    if (!fresh(c, o)) return o;
    bool done = true;
    for (std::size_t w = 0; w < 2; ++w) {
      const std::int32_t p = c.body.pos(w).position;
      const bool at_target = reached(w, p, c.body.tuning);
      const bool stuck = stalled(c, w);
      if (!at_target && stuck) {
        ReasonText why;
        why.append(to_string(c.body.motor(w).port())).append(" stalled at ").append_int(std::int64_t{p} - start_pos_[w])
            .append(" of ").append_int(counts_[w]).append(" counts");
        return fail(c, why);
      }
      if (!at_target || !still(c, w)) done = false;
    }
    if (!done) return Outcome::running;
    detail_.clear();
    const std::int32_t t = progress_tenths(c);
    detail_.append(step().kind == action::Kind::turn ? "turned " : "drove ").append_fixed(t, 1)
        .append(step().kind == action::Kind::turn ? " deg" : " mm");
    return Outcome::finished;
  }

  /// Distance (mm) or angle (deg) done so far, in tenths, from the wheels' positions.
  std::int32_t progress_tenths(const Ctx& c) const noexcept {
    const action::Kind k = step().kind;
    if (k != action::Kind::drive_distance && k != action::Kind::turn) return 0;
    const double l = mm_for_counts(std::int64_t{c.body.left_pos.position} - start_pos_[0], c.body, c.body.left);
    const double r = mm_for_counts(std::int64_t{c.body.right_pos.position} - start_pos_[1], c.body, c.body.right);
    const double v = k == action::Kind::turn ? (r - l) / c.body.geo.wheel_base_mm * 180.0 / kPi
                                             : (l + r) / 2.0;
    return static_cast<std::int32_t>(std::lround(v * 10.0));
  }
  void append_progress(std::int32_t tenths) noexcept {
    const action::Kind k = step().kind;
    if (k != action::Kind::drive_distance && k != action::Kind::turn) return;
    detail_.append(" after ").append_fixed(tenths, 1).append(k == action::Kind::turn ? " deg" : " mm");
  }

  Outcome tick_forever(Ctx& c) noexcept {
    Outcome o = Outcome::running;
    if (!fresh(c, o)) return o;
    const action::Step& s = step();
    for (std::size_t w = 0; w < 2; ++w) {
      const bool commanded = (w == 0 ? s.speed : s.speed_right) != 0;
      if (stalled(c, w) && commanded) {
        ReasonText why;
        why.append(to_string(c.body.motor(w).port())).append(" stalled (no progress for ")
            .append_int(static_cast<std::int64_t>(c.body.tuning.stall_ms)).append(" ms)");
        return fail(c, why);
      }
    }
    return Outcome::running;
  }

  Outcome tick_stop(Ctx& c) noexcept {
    Outcome o = Outcome::running;
    if (!fresh(c, o)) return o;
    if (still(c, 0) && still(c, 1)) {
      detail_.clear();
      detail_.append("stopped (").append(to_string(step().stop)).append(") in ")
          .append_int(static_cast<std::int64_t>(c.now - started_)).append(" ms");
      return Outcome::finished;
    }
    if (c.now - started_ >= c.body.tuning.stop_timeout_ms) return still_turning(c);
    return Outcome::running;
  }

  Outcome still_turning(Ctx& c) noexcept {
    ReasonText why;
    const std::size_t w = still(c, 0) ? 1 : 0;
    why.append(to_string(c.body.motor(w).port())).append(" still turning ")
        .append_int(static_cast<std::int64_t>(c.now - started_)).append(" ms after stop");
    return fail(c, why);
  }

  Outcome tick_pause(Ctx& c) noexcept {
    Outcome o = Outcome::running;
    const action::Step& s = step();
    if (!fresh(c, o)) return o;
    const bool settled = (!c.body.left.present() || still(c, 0)) && (!c.body.right.present() || still(c, 1));
    if (!settled || c.now - started_ < s.ms) {
      if (c.now - started_ >= s.ms + c.body.tuning.stop_timeout_ms) return still_turning(c);
      return Outcome::running;
    }
    // Settled: this tick's sensor readings were taken with the robot still.
    for (std::size_t i = 0; i < 4; ++i) {
      if ((s.sensors & (1u << i)) == 0) continue;
      const SensorReadings& r = c.body.readings[i];
      if (!r.valid || r.info_stale || r.at < c.now) {
        if (c.now - started_ >= s.ms + c.body.tuning.stale_ms) {
          ReasonText why;
          why.append(to_string(static_cast<Dev>(index(Dev::in1) + i))).append(": no good reading after settling");
          return fail(c, why);
        }
        return Outcome::running;  // next tick
      }
    }
    for (std::size_t i = 0; i < 4; ++i) {
      if ((s.sensors & (1u << i)) == 0) continue;
      const SensorReadings& r = c.body.readings[i];
      Report rep;
      rep.port = static_cast<Dev>(index(Dev::in1) + i);
      rep.mode = ModeName(c.body.sensors[i].info().mode_name());
      rep.count = r.count;
      for (std::size_t k = 0; k < r.count; ++k) rep.values[k] = r.values[k];
      c.reports.push(rep);
    }
    detail_.clear();
    detail_.append("settled in ").append_int(static_cast<std::int64_t>(c.now - started_)).append(" ms");
    return Outcome::finished;
  }

  void stop_motors(Ctx& c, StopAction how) noexcept {
    ReasonText ignored;  // a refused stop (motor gone) leaves nothing to stop
    for (std::size_t w = 0; w < 2; ++w) {
      Tacho& m = c.body.motor(w);
      if (!m.present()) continue;
      StopAction a = how;
      if ((m.info().stop_actions & bit(a)) == 0) a = StopAction::coast;  // every motor can coast
      if ((m.info().stop_actions & bit(a)) == 0) a = StopAction::brake;
      m.apply(Stop{a}, c.writes, ignored);
    }
    cmd_at_ = c.now;
  }

  action::Plan plan_;
  std::uint8_t index_ = 0;
  std::uint16_t iteration_ = 0;
  Phase phase_ = Phase::idle;
  Millis started_ = 0, cmd_at_ = 0, due_ = 0, left_ = 0;
  Millis bound_ = 0;  // the watchdog bound RunForever was last written run-timed to
  bool waiting_ = false;
  std::int32_t counts_[2] = {0, 0}, start_pos_[2] = {0, 0}, target_[2] = {0, 0};
  std::int32_t anchor_[2] = {0, 0};
  Millis progress_at_[2] = {0, 0};
  ReasonText detail_;
  EventKind cause_ = EventKind::OBSTACLE_DETECTED;
};

}  // namespace ev3proto::robot
