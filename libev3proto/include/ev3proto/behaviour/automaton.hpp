/// @file behaviour/automaton.hpp
/// @brief The automaton that runs a parsed, checked behaviour (docs/behaviours.md "How a behaviour
/// runs"): sans-I/O, no heap, no exceptions, like the protocol cores.
///
/// Inputs: the lifecycle (start, pause, resume, go_on = CONTINUE, stop, restart), the end of the
/// running action (finished, failed), the event that interrupted it, and on each control tick the
/// readings of the sensors its conditions and reports use, and the time. Outputs (poll()): the plan
/// of the state entered (robot/actions.hpp action::Plan, plan()), pause / resume / halt of the
/// motors, and the reports: ACTION_OK with the finished action's id, ACTION_INTERR with the warning,
/// ACTION_ERR, SENSOR_VALUE of a reported sensor; `done` when the behaviour reached its stop state.
///
/// The rules:
/// - Entering a state resolves its steps' arguments (a random param is drawn then, from the Rng
///   seeded with the param `seed` at every start) into one Plan: run -> RunForever, drive ->
///   DriveDistance, turn -> Turn, stop -> Stop, pause -> Pause with the reported sensors' ports,
///   wait -> Wait, repeat N -> Plan.times. Each step is interrupted by exactly the events the state
///   reacts to with a state (not `ignore`), but for a step that only moves backwards: the bumper and
///   the ultrasonic face forward, so OBSTACLE_DETECTED and PROXIMITY_ALERT do not interrupt it (as
///   robot/actions.hpp's DriveDistance and RunForever have it).
/// - A finished action: ACTION_OK(id), then the default next state; the stop state `end` ends the
///   behaviour (done). A failed one: ACTION_ERR, then it waits for RESTART (or a new BEHAVIOUR).
/// - An event the state reacts to with a state: that state is entered (the runner has stopped the
///   motors). A reaction to `end` is one the behaviour cannot resolve by itself: a warning
///   (OBSTACLE_DETECTED, PROXIMITY_ALERT) gives ACTION_INTERR and waits for CONTINUE, which then
///   ends it; another event (DEVICE_ERROR ...) gives ACTION_ERR. An event without a reaction, or
///   `ignore`d, changes nothing.
/// - Each tick: the state's conditions (`when`) in order, then the behaviour-wide ones; the first
///   that holds halts the motors (the step's stop=) and is taken like a reaction (to `end`: done).
///   The reported sensors go out every `report ... every` period (1 s unless written) while running.
#pragma once

#include <cstddef>
#include <cstdint>

#include "../ring.hpp"
#include "../robot/actions.hpp"
#include "definition.hpp"

namespace ev3proto::behaviour {

/// One output of the automaton (see the file comment).
struct Output {
  enum class Kind : std::uint8_t {
    start,        ///< start plan() (the state `state` entered); the running plan is replaced
    pause,        ///< stop the motors, keep the running plan's progress
    resume,       ///< continue the paused plan (the remainder of the same action)
    halt,         ///< stop the motors with `stop`, drop the running plan
    ok,           ///< ACTION_OK(id): the action of state `state` finished
    interrupted,  ///< ACTION_INTERR(id, event): waiting for CONTINUE
    error,        ///< ACTION_ERR(id): waiting for RESTART
    report,       ///< SENSOR_VALUE of `sensor`
    done,         ///< the stop state reached: the behaviour is over (motors stopped with `stop`)
  };
  Kind kind = Kind::start;
  std::uint8_t state = kNone;
  std::uint32_t id = 0;
  EventKind event = EventKind::OBSTACLE_DETECTED;
  Sensor sensor = Sensor::distance;
  robot::StopAction stop = robot::StopAction::brake;
};

constexpr std::string_view to_string(Output::Kind k) noexcept {
  switch (k) {
    case Output::Kind::start: return "start";
    case Output::Kind::pause: return "pause";
    case Output::Kind::resume: return "resume";
    case Output::Kind::halt: return "halt";
    case Output::Kind::ok: return "ACTION_OK";
    case Output::Kind::interrupted: return "ACTION_INTERR";
    case Output::Kind::error: return "ACTION_ERR";
    case Output::Kind::report: return "SENSOR_VALUE";
    case Output::Kind::done: return "done";
  }
  return "?";
}

/// A sensor's last reading in base units (mm, 0/1, colour code, degrees), for conditions.
struct Reading {
  bool valid = false;
  std::int32_t value = 0;
};

/// Where the automaton is in its lifecycle.
enum class Phase : std::uint8_t {
  idle,           ///< not started, or stopped
  running,        ///< the current state's plan runs
  paused,         ///< PAUSE: the plan's progress kept, motors stopped
  wait_continue,  ///< after ACTION_INTERR
  wait_restart,   ///< after ACTION_ERR
  done,           ///< the stop state was reached
};

constexpr std::string_view to_string(Phase p) noexcept {
  switch (p) {
    case Phase::idle: return "idle";
    case Phase::running: return "running";
    case Phase::paused: return "paused";
    case Phase::wait_continue: return "wait_continue";
    case Phase::wait_restart: return "wait_restart";
    case Phase::done: return "done";
  }
  return "?";
}

/// The automaton of one behaviour (see the file comment).
class Automaton {
 public:
  static constexpr std::size_t kMaxOutputs = 16;
  static constexpr robot::Millis kNever = ~robot::Millis{0};

  /// Holds @p def (parsed, its BEHAVIOUR arguments applied, checked). @p sensor_ports gives, for
  /// each Sensor, the input ports' bit (bit i = in(i+1)) a Pause reads it on (0: none).
  void load(const Definition& def, const std::uint8_t (&sensor_ports)[kSensorCount]) noexcept {
    def_ = def;
    for (std::size_t i = 0; i < kSensorCount; ++i) ports_[i] = sensor_ports[i];
    phase_ = Phase::idle;
    outs_.clear();
  }

  // ------------------------------------------------------------------ inputs: the lifecycle

  /// START (and RESTART): from the start state, the random numbers seeded again, ids from 0.
  void start(robot::Millis now) noexcept {
    rng_ = Rng(def_.seed());
    id_ = 0;
    next_report_ = now + period();
    enter(def_.start);
  }
  /// RESTART: the same as start().
  void restart(robot::Millis now) noexcept { start(now); }

  /// PAUSE: the motors stop, the place is kept (a pause while waiting for CONTINUE changes nothing).
  void pause() noexcept {
    if (phase_ != Phase::running) return;
    phase_ = Phase::paused;
    push(Output::Kind::pause);
  }

  /// RESUME: the same action goes on (its remainder); the reports from now on.
  void resume(robot::Millis now) noexcept {
    if (phase_ != Phase::paused) return;
    phase_ = Phase::running;
    next_report_ = now + period();
    push(Output::Kind::resume);
  }

  /// CONTINUE after ACTION_INTERR: the reaction's target is entered (the stop state: done).
  void go_on(robot::Millis now) noexcept {
    if (phase_ != Phase::wait_continue) return;
    next_report_ = now + period();
    enter(pending_);
  }

  /// STOP / STANDBY (or a critical event): the motors stop, the behaviour ends.
  void stop() noexcept {
    if (phase_ == Phase::running || phase_ == Phase::paused) push(Output::Kind::halt);
    phase_ = Phase::idle;
  }

  // ------------------------------------------------------------------ inputs: the running plan

  /// The current state's plan finished: ACTION_OK, then the default next state.
  void finished() noexcept {
    if (phase_ != Phase::running) return;
    Output o = make(Output::Kind::ok);
    o.id = id_++;
    push(o);
    enter(def_.states[state_].next);
  }

  /// The current state's plan failed: ACTION_ERR, wait for RESTART.
  void failed() noexcept {
    if (phase_ != Phase::running) return;
    fail();
  }

  /// Event @p e interrupted the plan, or came while it runs: its reaction is taken. Returns true when
  /// the state reacts to it with a state (the plan is then over).
  bool event(EventKind e) noexcept {
    if (phase_ != Phase::running) return false;
    const Reaction* r = def_.on_event(state_, e);
    if (r == nullptr || r->target == kIgnore) return false;
    if (r->target != def_.stop) {
      enter(r->target);
    } else if (e == EventKind::OBSTACLE_DETECTED || e == EventKind::PROXIMITY_ALERT) {
      Output o = make(Output::Kind::interrupted);
      o.id = id_;
      o.event = e;
      push(o);
      pending_ = r->target;
      phase_ = Phase::wait_continue;
    } else {
      fail();
    }
    return true;
  }

  // ------------------------------------------------------------------ inputs: time

  /// The control tick at @p now with the last readings (indexed by Sensor): the conditions, then the
  /// reports when due.
  void tick(robot::Millis now, const Reading (&readings)[kSensorCount]) noexcept {
    if (phase_ != Phase::running) return;
    for (std::size_t k = 0;; ++k) {
      const Reaction* r = def_.condition(state_, k);
      if (r == nullptr) break;
      const Reading& rd = readings[static_cast<std::size_t>(r->sensor)];
      if (!rd.valid || !def_.holds(*r, rd.value)) continue;
      Output h = make(Output::Kind::halt);
      h.stop = halt_of(state_);
      push(h);
      enter(r->target);
      break;
    }
    if (phase_ != Phase::running || def_.report.count == 0 || now < next_report_) return;
    for (std::uint8_t i = 0; i < def_.report.count; ++i) {
      Output o = make(Output::Kind::report);
      o.sensor = def_.report.sensors[i];
      push(o);
    }
    next_report_ = now + period();
  }

  // ------------------------------------------------------------------ outputs

  /// The next output, in order (false when none).
  bool poll(Output& out) noexcept {
    return outs_.pop(out);
  }

  /// The plan of the state entered last (the one an Output::start means).
  const robot::action::Plan& plan() const noexcept { return plan_; }
  /// When tick() must be called at the latest for the reports (kNever when none are due).
  robot::Millis deadline() const noexcept {
    return phase_ == Phase::running && def_.report.count > 0 ? next_report_ : kNever;
  }

  // ------------------------------------------------------------------ observers

  const Definition& definition() const noexcept { return def_; }
  Phase phase() const noexcept { return phase_; }
  /// The current state (meaningful once started).
  std::uint8_t state() const noexcept { return state_; }
  /// The id the next ACTION_OK carries (the finished actions since the start).
  std::uint32_t next_id() const noexcept { return id_; }
  /// The sensors the current state's conditions and the reports read (bit i = Sensor i).
  std::uint8_t sensors_read() const noexcept {
    std::uint8_t m = 0;
    if (phase_ != Phase::running && phase_ != Phase::paused) return m;
    for (std::uint8_t i = 0; i < def_.report.count; ++i)
      m = static_cast<std::uint8_t>(m | (1u << static_cast<unsigned>(def_.report.sensors[i])));
    for (std::size_t k = 0;; ++k) {
      const Reaction* r = def_.condition(state_, k);
      if (r == nullptr) break;
      m = static_cast<std::uint8_t>(m | (1u << static_cast<unsigned>(r->sensor)));
    }
    return m;
  }
  /// The report period (ms).
  robot::Millis period() const noexcept { return static_cast<robot::Millis>(def_.report.period.value); }

 private:
  Output make(Output::Kind k) const noexcept {
    Output o;
    o.kind = k;
    o.state = state_;
    return o;
  }
  void push(Output::Kind k) noexcept { push(make(k)); }
  void push(const Output& o) noexcept {
    outs_.push_over(o);  // never full: every input gives a handful and they are drained
  }

  void fail() noexcept {
    Output o = make(Output::Kind::error);
    o.id = id_;
    push(o);
    phase_ = Phase::wait_restart;
  }

  /// The stop mode of state @p s's first step (run / drive / turn: stop=, stop: its mode).
  robot::StopAction halt_of(std::uint8_t s) noexcept {
    const State& st = def_.states[s];
    if (st.step_count == 0) return robot::StopAction::brake;
    const Step& step = def_.steps[st.first_step];
    const Arg& a = step.action == ActionKind::stop ? step.main : step.halt;
    return a.kind == Arg::Kind::none ? robot::StopAction::brake : static_cast<robot::StopAction>(def_.value(a, rng_));
  }

  /// True for a step that only moves the robot backwards.
  static bool backwards(const robot::action::Step& a) noexcept {
    return (a.kind == robot::action::Kind::drive_distance && a.mm < 0) ||
           (a.kind == robot::action::Kind::run_forever && a.speed <= 0 && a.speed_right <= 0);
  }

  /// Enters state @p s: the stop state ends the behaviour, any other starts its plan.
  void enter(std::uint8_t s) noexcept {
    if (s >= def_.state_count) {  // a finishing state without a next one: the checker refuses it
      fail();
      return;
    }
    state_ = s;
    if (s == def_.stop) {
      Output o = make(Output::Kind::done);
      o.stop = halt_of(s);
      push(o);
      phase_ = Phase::done;
      return;
    }
    robot::EventSet interrupts = 0;
    for (std::size_t e = 0; e < robot::kEventKindCount; ++e) {
      const Reaction* r = def_.on_event(s, static_cast<EventKind>(e));
      if (r != nullptr && r->target != kIgnore)
        interrupts = static_cast<robot::EventSet>(interrupts | robot::event_bit(static_cast<robot::EventKind>(e)));
    }
    std::uint8_t pause_ports = 0;
    for (std::uint8_t i = 0; i < def_.report.count; ++i)
      pause_ports = static_cast<std::uint8_t>(pause_ports | ports_[static_cast<std::size_t>(def_.report.sensors[i])]);
    const State& st = def_.states[s];
    plan_ = robot::action::Plan{};
    plan_.times = st.repeat;
    for (std::uint8_t k = 0; k < st.step_count && k < robot::action::kMaxSteps; ++k) {
      const Step& step = def_.steps[st.first_step + k];
      const std::int32_t main = def_.value(step.main, rng_);
      const std::int32_t speed = def_.value(step.speed, rng_);
      const robot::StopAction halt = step.halt.kind == Arg::Kind::none
                                         ? robot::StopAction::brake
                                         : static_cast<robot::StopAction>(def_.value(step.halt, rng_));
      robot::action::Step a;
      switch (step.action) {
        case ActionKind::run: a = robot::action::run_forever(main, main, halt); break;
        case ActionKind::drive: a = robot::action::drive_distance(main, speed, halt); break;
        case ActionKind::turn: a = robot::action::turn(main, speed, halt); break;
        case ActionKind::stop: a = robot::action::stop(static_cast<robot::StopAction>(main)); break;
        case ActionKind::pause: a = robot::action::pause(static_cast<robot::Millis>(main), pause_ports); break;
        case ActionKind::wait: a = robot::action::wait(static_cast<robot::Millis>(main)); break;
        case ActionKind::repeat: break;  // not a step: State::repeat
      }
      a.interrupts = interrupts;
      if (backwards(a))  // the bumper and the ultrasonic face forward (robot::action::kForwardWarnings)
        a.interrupts = static_cast<robot::EventSet>(a.interrupts & ~robot::action::kForwardWarnings);
      plan_.steps[plan_.count++] = a;
    }
    phase_ = Phase::running;
    push(Output::Kind::start);
  }

  Definition def_;
  std::uint8_t ports_[kSensorCount] = {};
  Rng rng_;
  Phase phase_ = Phase::idle;
  std::uint8_t state_ = 0;
  std::uint8_t pending_ = kNone;
  std::uint32_t id_ = 0;
  robot::Millis next_report_ = 0;
  robot::action::Plan plan_;
  Ring<Output, kMaxOutputs> outs_;
};

}  // namespace ev3proto::behaviour
