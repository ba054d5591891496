/// @file robot_runtime.hpp
/// @brief The robot runtime: the sans-I/O robot side of an agent. It takes the agent core's
///        controls (start / pause / resume / stop / restart of the loaded behaviour, LED patterns),
///        the devices the device layer finds and loses, the readings it takes, and time; it gives
///        the device writes to make, action results (for the core's action_ok / action_interrupted /
///        action_failed), events (DEVICE_CONNECTED ... BATTERY_LOW: for the core and the master's
///        EVENT), sensor reports (SENSOR_VALUE), the reads to take next tick and its next deadline.
///
/// No I/O, no heap, no clocks, no exceptions (like the agent core). docs/devices.md "The robot
/// runtime" shows the loop that wires it to the device layer and the agent core.
///
/// The control tick. While an action moves the motors the runtime wants a tick every `tick_ms`
/// (20 ms): the device layer reads what plan_reads() lists (both wheels' position, the bumper, the
/// ultrasonic: 4 preads), the runtime feeds the detectors, handles the events raised (an obstacle
/// stops the motors in that same tick: the stop write is queued before tick() returns), then checks
/// the action's end condition. Otherwise it ticks every `idle_tick_ms` (100 ms) to keep watching
/// the sensors, and reads the battery every `battery_period_ms` (1 s).
///
/// Behaviours: check_behaviour() is the robot's check on receipt (the agent core asks it
/// before it answers BEHAVIOUR: robot_link.hpp): a built-in (behaviours/*.bhv: explore, exploit,
/// drive, wait) or `custom` (the definition in the first argument) is parsed, BEHAVIOUR's key=value
/// arguments applied, and checked on model A; a refusal's reason (`line 4 col 12: ...`) goes into
/// the NOT. START / RESTART parse and check the kept request again (one scratch Definition; a parse
/// is cheap beside a behaviour's run) and run it through behaviour::Automaton: each state's plan on
/// the ActionRunner, its results, the events that interrupt it and this tick's readings fed back
/// (docs/behaviours.md "How a behaviour runs"). A request that cannot run (a core without the check)
/// fails the START (ACTION_ERR) with the reason.
#pragma once

#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "behaviour/automaton.hpp"
#include "behaviour/request.hpp"
#include "core.hpp"
#include "robot/actions.hpp"
#include "robot/behaviours.hpp"
#include "robot/command.hpp"
#include "robot/odometry.hpp"
#include "robot/device.hpp"
#include "robot/events.hpp"
#include "robot/leds.hpp"
#include "robot/model.hpp"
#include "robot/text.hpp"

namespace ev3proto::robot {

/// Construction parameters of a Runtime.
struct RuntimeConfig {
  PortMap ports;                      ///< model A's ports (--ports)
  Geometry geo;                       ///< wheel diameter, wheel base
  MoveTuning tuning;                  ///< end conditions of the actions
  Millis tick_ms = 20;                ///< control tick while the motors may move
  Millis idle_tick_ms = 100;          ///< tick while no action moves the motors
  Millis battery_period_ms = 1000;    ///< battery read period
  Millis mode_retry_ms = 1000;        ///< a sensor not in its mode is set again after this
  Fixed proximity{200, 1};            ///< PROXIMITY_ALERT below this (cm)
  Fixed proximity_hysteresis{50, 1};  ///< re-armed this far above it
  std::uint8_t proximity_confirm = 2; ///< readings in a row below it
  std::int32_t battery_low_uv = 6200000;  ///< BATTERY_LOW below this (µV) ...
  Millis battery_low_ms = 3000;           ///< ... for this long
  Millis touch_release_ms = 50;           ///< a bumper release counts after this long
  /// Contact watchdog: wheels turning this long after the last contact with a master are stopped
  /// (0: no watchdog). Armed by the first contact() (see Runtime::contact).
  Millis watchdog_ms = 500;
  /// Odometry: where the robot starts (the operator's word for it), and how often its pose is
  /// reported while it works and has moved (0: never) as SENSOR_VALUE(pose, ODOM, x mm, y mm,
  /// heading degrees).
  Pose start_pose{};
  Millis pose_ms = 1000;
};

/// The contact watchdog for heartbeat @p heartbeat_ms: the default (500 ms), or 5 heartbeats when
/// that is longer (a contact every heartbeat, several of them lost, before a hold), at most 10 min.
constexpr Millis watchdog_for(Millis heartbeat_ms) noexcept {
  const Millis d = RuntimeConfig{}.watchdog_ms, five = 5 * heartbeat_ms;
  return five <= d ? d : five < 600000 ? five : 600000;
}

/// One read the device layer must take this tick.
struct Read {
  Dev dev = Dev::outA;
  Attr attr = Attr::position;
};

/// The reads of one tick, in order.
struct ReadPlan {
  static constexpr std::size_t kMax = 48;
  Read reads[kMax];
  std::size_t count = 0;
  void add(Dev d, Attr a) noexcept {
    if (count < kMax) reads[count++] = Read{d, a};
  }
};

/// An action's end, for the agent core.
struct ActionResult {
  Outcome outcome = Outcome::finished;  ///< finished -> action_ok, interrupted -> action_interrupted,
                                        ///< failed -> action_failed
  Warning warning = Warning::OBSTACLE_DETECTED;  ///< the warning of an interruption
  ReasonText detail;                        ///< what happened, for the log
};

/// The robot runtime of model A (see the file comment).
class Runtime {
 public:
  static constexpr Millis kNever = ~Millis{0};

  explicit Runtime(const RuntimeConfig& cfg, Millis now) noexcept : cfg_(cfg) {
    body_.geo = cfg.geo;
    body_.tuning = cfg.tuning;
    body_.left.bind(cfg.ports.of(Role::left));
    body_.right.bind(cfg.ports.of(Role::right));
    for (std::size_t i = 0; i < 4; ++i) body_.sensors[i].bind(static_cast<Dev>(index(Dev::in1) + i));
    touch_.release_ms = cfg.touch_release_ms;
    proximity_.threshold = cfg.proximity;
    proximity_.hysteresis = cfg.proximity_hysteresis;
    proximity_.confirm = cfg.proximity_confirm;
    battery_watch_.threshold_uv = cfg.battery_low_uv;
    battery_watch_.hold_ms = cfg.battery_low_ms;
    next_tick_ = now;
    next_battery_ = now;
    odometry_ = Odometry(cfg.start_pose);
  }

  // ------------------------------------------------------------------ inputs: devices

  /// The device layer found @p info on a port (at start and on every later plug).
  void device_connected(const DeviceInfo& info, Millis now) noexcept {
    if (!is_port(info.dev)) return;
    if (attached_[index(info.dev)]) detach(info.dev);  // a replug the layer saw as one change
    Role r{};
    const bool has_role = cfg_.ports.role_on(info.dev, r);
    if (has_role && info.driver != driver_of(r)) {
      Event e = event(EventKind::DEVICE_ERROR, info.dev, now);
      e.detail.append(info.driver_name.view()).append(" where model A expects ").append(to_string(driver_of(r)))
          .append(" (").append(to_string(r)).append(")");
      events_.push(e);
      pump(now);
      return;
    }
    Event e = event(EventKind::DEVICE_CONNECTED, info.dev, now);
    e.detail.append(info.driver_name.view());
    if (has_role) {
      attached_[index(info.dev)] = true;
      plugged_ |= role_bit(r);
      e.bits = role_bit(r);
      error_[index(info.dev)] = false;
      if (r == Role::left || r == Role::right) {
        const std::size_t w = r == Role::left ? 0 : 1;
        body_.motor(w).attach(info.motor);
        body_.pos(w).clear();
        ReasonText ignored;
        body_.motor(w).apply(Reset{}, writes_, ignored);  // a clean motor: no leftover setpoints
      } else {
        const std::size_t i = Body::in_index(info.dev);
        body_.sensors[i].attach(info.sensor);
        body_.readings[i].clear();
        if (r == Role::touch) touch_.reset();
        if (r == Role::ultrasonic) proximity_.reset();
        ensure_mode(i, r, now);
      }
    }
    events_.push(e);
    pump(now);
  }

  /// A device appeared whose self-description is garbage (@p why names the file): not used.
  void device_faulty(Dev dev, std::string_view why, Millis now) noexcept {
    Event e = event(EventKind::DEVICE_ERROR, dev, now);
    e.detail.append(why);
    events_.push(e);
    pump(now);
  }

  /// The device on @p dev is gone (ENODEV, or its directory vanished).
  void device_disconnected(Dev dev, Millis now) noexcept {
    if (!is_port(dev)) return;
    Event e = event(EventKind::DEVICE_DISCONNECTED, dev, now);
    Role r{};
    if (attached_[index(dev)] && cfg_.ports.role_on(dev, r)) e.bits = role_bit(r);
    detach(dev);
    events_.push(e);
    pump(now);
  }

  /// A status LED is there, with its max_brightness.
  void led_present(Dev led, std::int32_t max_brightness) noexcept {
    if (!is_led(led) || max_brightness <= 0) return;
    led_max_[index(led) - index(Dev::led_left_red)] = max_brightness;
  }
  /// The battery (power_supply) is there: its voltage is watched.
  void battery_present(bool present) noexcept { battery_ = present; }

  // ------------------------------------------------------------------ inputs: readings

  /// The reads to take this tick (call when now >= next_deadline(), then reading() for each, then
  /// tick()).
  void plan_reads(ReadPlan& p, Millis now) const noexcept {
    p.count = 0;
    if (off_) return;
    for (std::size_t w = 0; w < 2; ++w)
      if (body_.motor(w).present()) p.add(body_.motor(w).port(), Attr::position);
    Needs n = runner_.needs();
    n.sensor_ports = static_cast<std::uint8_t>(n.sensor_ports | behaviour_ports());
    for (std::size_t i = 0; i < 4; ++i) {
      const Sensor& s = body_.sensors[i];
      if (!s.present()) continue;
      const Dev d = s.port();
      if (body_.readings[i].info_stale) {
        for (Attr a : {Attr::mode, Attr::decimals, Attr::num_values, Attr::units}) p.add(d, a);
        continue;
      }
      Role r{};
      const bool watched = cfg_.ports.role_on(d, r) && (r == Role::touch || (r == Role::ultrasonic && in_cm(s)));
      if ((n.sensor_ports & (1u << i)) != 0) {
        for (std::size_t k = 0; k < s.info().num_values; ++k) p.add(d, value_attr(k));
      } else if (watched) {
        p.add(d, Attr::value0);
      }
    }
    if (battery_ && now >= next_battery_) p.add(Dev::battery, Attr::voltage_now);
  }

  /// The text read from @p attr of @p dev at @p now. Garbage is ignored (the last good value
  /// stays) and raises one DEVICE_ERROR until a good value comes. Returns false for garbage.
  bool reading(Dev dev, Attr attr, std::string_view text, Millis now) noexcept {
    if (dev == Dev::battery) {
      if (attr != Attr::voltage_now) return false;
      next_battery_ = now + cfg_.battery_period_ms;
      std::int32_t uv = 0;
      if (!parse_int(text, uv) || uv < 0) return garbage(dev, attr, text, "is not a voltage in µV", now);
      good(dev);
      if (battery_watch_.update(uv, now)) {
        Event e = event(EventKind::BATTERY_LOW, Dev::battery, now);
        e.detail.append_fixed(uv / 1000, 3).append(" V");
        events_.push(e);
      }
      return true;
    }
    if (!is_port(dev) || !attached_[index(dev)]) return false;
    if (is_out_port(dev)) {
      if (attr != Attr::position) return false;
      std::int32_t p = 0;
      if (!parse_int(text, p)) return garbage(dev, attr, text, "is not a position", now);
      good(dev);
      body_.pos(dev == body_.left.port() ? 0 : 1).update(p, now);
      return true;
    }
    const std::size_t i = Body::in_index(dev);
    Sensor& s = body_.sensors[i];
    SensorReadings& r = body_.readings[i];
    if (attr == Attr::mode || attr == Attr::decimals || attr == Attr::num_values || attr == Attr::units)
      return info_text(i, attr, text, now);
    if (attr < Attr::value0 || attr > Attr::value7 || r.info_stale) return false;
    const std::size_t k = static_cast<std::size_t>(attr) - static_cast<std::size_t>(Attr::value0);
    std::int32_t raw = 0;
    if (!parse_int(text, raw)) return garbage(dev, attr, text, "is not a number", now);
    const Fixed v{raw, s.info().decimals};
    Role role{};
    cfg_.ports.role_on(dev, role);
    if (k == 0 && role == Role::touch && raw != 0 && raw != 1)
      return garbage(dev, attr, text, "is not 0 or 1 (TOUCH)", now);
    if (k == 0 && role == Role::ultrasonic && in_cm(s) && (v < Fixed{0, 0} || Fixed{255, 0} < v))
      return garbage(dev, attr, text, "is outside 0..255 cm", now);
    good(dev);
    if (k == 0 || r.at != now) {  // a new tick's reading starts with value0
      r.count = 0;
      r.at = now;
    }
    r.values[k] = v;
    if (k + 1 > r.count) r.count = static_cast<std::uint8_t>(k + 1);
    r.valid = true;
    if (k == 0) detect(dev, role, v, now);
    return true;
  }

  /// A read failed with @p err (not ENODEV: that is device_disconnected()): one DEVICE_ERROR.
  void read_failed(Dev dev, Attr attr, int err, Millis now) noexcept {
    if (dev == Dev::battery && attr == Attr::voltage_now) next_battery_ = now + cfg_.battery_period_ms;
    ReasonText why;
    why.append("reading ").append(to_string(attr)).append(" failed (").append(errno_name(err)).append(")");
    raise_error(dev, why, now);
    pump(now);
  }

  /// A write failed with @p err (not ENODEV: that is device_disconnected()). Call it before making
  /// the next write: the writes queued for that device up to its next `command` are dropped (that
  /// command would run with the old setpoint). EBUSY on `position` is the driver's "the motor runs
  /// or holds"; a failed motor write stops the running action.
  void write_failed(const Write& w, int err, Millis now) noexcept {
    if (w.attr != Attr::command) writes_.drop_through_command(w.dev);
    ReasonText why;
    if (w.attr == Attr::position && err == EBUSY) {
      why.append("position is busy: the motor runs or holds (EBUSY); stop it with coast or brake first");
    } else {
      why.append("writing ").append(to_string(w.attr)).append(" ");
      append_quoted(why, w.value.view());
      why.append(" failed (").append(errno_name(err)).append(")");
    }
    if (w.attr == Attr::mode && is_in_port(w.dev) && attached_[index(w.dev)]) {
      const std::size_t i = Body::in_index(w.dev);
      body_.readings[i].info_stale = true;  // which mode it is in now: read it back
      body_.readings[i].valid = false;
      body_.sensors[i].info().mode = -1;
      mode_retry_at_[i] = now + cfg_.mode_retry_ms;
    }
    error_[index(w.dev)] = false;  // always report a failed write
    raise_error(w.dev, why, now);
    if (is_out_port(w.dev) && runner_.active() && runner_.needs().motors) {
      ReasonText r;
      r.append(to_string(w.dev)).append(": ").append(why.view());
      fail_running(r, now);
    }
    pump(now);
  }

  // ------------------------------------------------------------------ inputs: time

  /// The control tick at @p now (after this tick's reading() calls): events handled (motors
  /// stopped at once when they interrupt the action), then the action's end condition.
  void tick(Millis now) noexcept {
    if (off_) return;
    dead_reckon(now);
    pump(now);
    retry_modes(now);
    watchdog(now);
    if (runner_.active() && !runner_.paused()) {
      Ctx c = ctx(now);
      outcome(runner_.tick(c), now);
    }
    if (behaviour_) {
      behaviour::Reading r[behaviour::kSensorCount];
      for (std::size_t i = 0; i < behaviour::kSensorCount; ++i) r[i] = reading_of(static_cast<behaviour::Sensor>(i));
      auto_.tick(now, r);
      follow(now);
    }
    watchdog(now);  // a step begun in this tick with the contact already too old is held at once
    next_tick_ = now + (runner_.moves_motors() && !runner_.paused() ? cfg_.tick_ms : cfg_.idle_tick_ms);
  }

  // ------------------------------------------------------------------ inputs: the agent core

  /// The node last heard a master (directly or through a relay) at @p at (robot_link.hpp feeds
  /// the agent core's last_heard() on every exchange). The first call arms the contact watchdog:
  /// from then on, wheels that turn watchdog_ms after the last contact are held (stopped, the
  /// action or behaviour paused as PAUSE would) until a contact comes, then they go on; a
  /// RunForever is written as run-timed ending at the bound (ActionRunner::renew), so the motor
  /// driver stops it there even when the program stalls. A runtime no node feeds (a test, a tool
  /// running a plan) has no master to lose and no watchdog.
  void contact(Millis at) noexcept {
    if (armed_ && at <= contact_) return;
    armed_ = true;
    contact_ = at;
    if (held_ && at < next_tick_) next_tick_ = at;  // let the wheels go on at the next call
  }

  /// A behaviour control from the agent core (AgentEvent::Kind::control) for the loaded behaviour
  /// @p name with @p args. pause and stop stop the motors in this call ("at once"): the agent core
  /// pauses on losing the master, so while it is lost the motors are stopped whatever the action.
  void control(ControlKind k, std::string_view name, const std::string_view* args, std::size_t n, Millis now) noexcept {
    if (held_) {  // the core's control takes over from the watchdog's hold
      held_ = false;
      if (k == ControlKind::pause) return;  // paused already
    }
    Ctx c = ctx(now);
    switch (k) {
      case ControlKind::start:
      case ControlKind::restart: {
        runner_.halt(c, cfg_.tuning.pause_stop);
        leave_behaviour();
        ReasonText why;
        if (off_) {
          why.append("battery low: the robot is shutting down");
          failed(why);
        } else if (!load_behaviour(name, args, n, why)) {
          failed(why);
        } else {
          behaviour_ = true;
          if (k == ControlKind::start)
            auto_.start(now);
          else
            auto_.restart(now);
          follow(now);
          return;
        }
        break;
      }
      case ControlKind::pause:
        if (behaviour_)
          auto_.pause();
        else
          runner_.pause(c);
        break;
      case ControlKind::resume:
        if (!behaviour_)
          result(runner_.resume(c));
        else if (auto_.phase() == behaviour::Phase::wait_continue)
          auto_.go_on(now);  // CONTINUE after ACTION_INTERR (the core resumes the motors)
        else
          auto_.resume(now);
        break;
      case ControlKind::stop:
        runner_.halt(c, cfg_.tuning.pause_stop);
        leave_behaviour();
        break;
    }
    follow(now);
    next_tick_ = now;
  }

  /// The robot's check of BEHAVIOUR @p name with @p args on receipt: parsed, arguments applied,
  /// checked on model A. True when it may run; otherwise false with the reason in @p why. It changes
  /// nothing but the scratch Definition (the running behaviour is the automaton's own copy).
  bool check_behaviour(std::string_view name, const std::string_view* args, std::size_t n, ReasonText& why) noexcept {
    return resolve(name, args, n, scratch_, why);
  }

  /// Runs @p plan now, outside any behaviour (tests and tools call it directly; a running behaviour is
  /// left). The result comes through poll_result().
  void run(const action::Plan& plan, Millis now) noexcept {
    leave_behaviour();
    held_ = false;  // a new plan: what was held is gone
    outcome(start_plan(plan, now), now);
  }

  /// The agent core's LED pattern: written to every LED found.
  void led(Led l) noexcept {
    for (std::size_t i = 0; i < kLedCount; ++i)
      if (led_max_[i] > 0) led_writes(l, led_dev(i), led_max_[i], writes_);
  }

  // ------------------------------------------------------------------ outputs

  /// The next device write, in order (false when none). Make every write before the next call.
  bool poll_write(Write& out) noexcept { return writes_.pop(out); }
  /// The next action result (false when none).
  bool poll_result(ActionResult& out) noexcept { return results_.pop(out); }
  /// The next event handled (false when none), for the agent core (robot_link.hpp: the device
  /// events and BATTERY_LOW to their spec actions, the rest to robot_event unless it interrupted
  /// the running action: Event::interrupted).
  bool poll_event(Event& out) noexcept { return out_events_.pop(out); }
  /// The next clean sensor reading a Pause took (agent core: sensor_report).
  bool poll_report(Report& out) noexcept { return reports_.pop(out); }

  /// When to tick next at the latest (kNever once the battery shut it down).
  Millis next_deadline() const noexcept {
    if (off_) return kNever;
    Millis d = next_tick_;
    const Millis a = runner_.deadline();
    if (a < d) d = a;
    const Millis b = behaviour_ ? auto_.deadline() : kNever;
    if (b < d) d = b;
    const Millis w = runner_.turns_motors() ? run_until() : kNever;
    if (w < d) d = w;
    return d;
  }

  // ------------------------------------------------------------------ observers

  /// The model's device bits plugged now (tell the core the missing ones after the first scan).
  std::uint32_t plugged() const noexcept { return plugged_; }
  /// The port of each role (the configuration's, `--ports`).
  const PortMap& ports() const noexcept { return cfg_.ports; }
  /// True once BATTERY_LOW was handled: motors stopped, nothing starts any more (exit cleanly).
  bool off() const noexcept { return off_; }
  /// True while an action runs or is paused.
  bool busy() const noexcept { return runner_.active(); }
  /// True while the contact watchdog holds the wheels.
  bool held() const noexcept { return held_; }
  /// Times the contact watchdog held the wheels.
  std::uint32_t holds() const noexcept { return holds_; }
  /// The last contact with a master (contact()); meaningful once armed.
  Millis last_contact() const noexcept { return contact_; }
  /// Until when the wheels may turn: the last contact + watchdog_ms (kNever: no watchdog armed).
  Millis run_until() const noexcept {
    return armed_ && cfg_.watchdog_ms != 0 ? contact_ + cfg_.watchdog_ms : kNever;
  }
  const Body& body() const noexcept { return body_; }
  const ActionRunner& runner() const noexcept { return runner_; }
  /// The automaton of the behaviour started last (its phase is idle when none runs).
  const behaviour::Automaton& automaton() const noexcept { return auto_; }
  /// Writes / events dropped because a queue was full (0 unless something is badly wrong).
  std::size_t dropped() const noexcept { return writes_.overflowed() + events_.dropped() + out_events_.dropped(); }

 private:
  Ctx ctx(Millis now) noexcept {
    Ctx c{body_, writes_, reports_, now};
    c.run_until = run_until();
    return c;
  }

  /// The contact watchdog at @p now: holds turning wheels once the bound has passed, lets them go
  /// on when a contact came, and otherwise moves a RunForever's run-timed bound on.
  void watchdog(Millis now) noexcept {
    const Millis until = run_until();
    if (until == kNever) return;
    if (held_) {
      if (now < until) {
        held_ = false;
        release(now);
      }
      return;
    }
    if (!runner_.turns_motors()) return;
    if (now >= until) {
      held_ = true;
      ++holds_;
      if (behaviour_) {
        auto_.pause();
        follow(now);
      } else {
        Ctx c = ctx(now);
        runner_.pause(c);
      }
      return;
    }
    Ctx c = ctx(now);
    if (!runner_.renew(c)) outcome(Outcome::failed, now);
  }

  /// The hold ends (a contact came, or the core resumes): what was paused goes on.
  void release(Millis now) noexcept {
    if (behaviour_) {
      auto_.resume(now);
      follow(now);
    } else {
      Ctx c = ctx(now);
      result(runner_.resume(c));
    }
  }

  static Event event(EventKind k, Dev d, Millis now) noexcept {
    Event e;
    e.kind = k;
    e.dev = d;
    e.at = now;
    return e;
  }

  static bool in_cm(const Sensor& s) noexcept {
    const std::string_view m = s.info().mode_name();
    return m == "US-DIST-CM" || m == "US-SI-CM";
  }

  void detach(Dev dev) noexcept {
    const std::size_t d = index(dev);
    Role r{};
    if (attached_[d] && cfg_.ports.role_on(dev, r)) plugged_ &= ~role_bit(r);
    attached_[d] = false;
    error_[d] = false;
    if (dev == body_.left.port() || dev == body_.right.port()) odometry_.rebase();  // its count starts again
    if (dev == body_.left.port()) {
      body_.left.detach();
      body_.left_pos.clear();
    } else if (dev == body_.right.port()) {
      body_.right.detach();
      body_.right_pos.clear();
    } else if (is_in_port(dev)) {
      body_.sensors[Body::in_index(dev)].detach();
      body_.readings[Body::in_index(dev)].clear();
    }
  }

  /// Sets sensor @p i to its role's mode (skipped when set; the ultrasonic's gap respected).
  void ensure_mode(std::size_t i, Role r, Millis now) noexcept {
    const std::string_view m = default_mode(r);
    if (m.empty()) return;
    ReasonText why;
    Millis retry = 0;
    switch (body_.sensors[i].set_mode(m, now, writes_, why, retry)) {
      case ModeOutcome::written:
        body_.readings[i].info_stale = true;
        body_.readings[i].valid = false;
        break;
      case ModeOutcome::unchanged: break;
      case ModeOutcome::too_soon: mode_retry_at_[i] = retry; break;
      case ModeOutcome::refused:
        raise_error(body_.sensors[i].port(), why, now);
        mode_retry_at_[i] = kNever;
        break;
    }
  }

  void retry_modes(Millis now) noexcept {
    for (std::size_t i = 0; i < 4; ++i) {
      const Dev d = static_cast<Dev>(index(Dev::in1) + i);
      Role r{};
      if (!attached_[index(d)] || body_.readings[i].info_stale || !cfg_.ports.role_on(d, r)) continue;
      if (body_.sensors[i].info().mode_name() == default_mode(r) || now < mode_retry_at_[i]) continue;
      mode_retry_at_[i] = now + cfg_.mode_retry_ms;
      ensure_mode(i, r, now);
    }
  }

  /// One of mode / decimals / num_values / units, read back after a mode write.
  bool info_text(std::size_t i, Attr attr, std::string_view text, Millis now) noexcept {
    Pending& p = pending_[i];
    const std::string_view t = chomp(text);
    switch (attr) {
      case Attr::mode: p.mode = Text<24>(t); p.got |= 1u; break;
      case Attr::decimals: p.decimals = Text<24>(t); p.got |= 2u; break;
      case Attr::num_values: p.num_values = Text<24>(t); p.got |= 4u; break;
      default: p.units = Text<24>(t); p.got |= 8u; break;
    }
    if (p.got != 15u) return true;
    p.got = 0;
    SensorTexts st;
    st.mode = p.mode.view();
    st.decimals = p.decimals.view();
    st.num_values = p.num_values.view();
    st.units = p.units.view();
    ReasonText why;
    if (!parse_sensor_mode(st, body_.sensors[i].info(), why)) {
      raise_error(body_.sensors[i].port(), why, now);
      return false;
    }
    body_.readings[i].info_stale = false;
    good(body_.sensors[i].port());
    return true;
  }

  bool garbage(Dev dev, Attr attr, std::string_view text, std::string_view what, Millis now) noexcept {
    ReasonText why;
    bad_file(why, to_string(attr), text, what);
    raise_error(dev, why, now);
    return false;
  }
  /// DEVICE_ERROR once until the device gives a good value again.
  void raise_error(Dev dev, const ReasonText& why, Millis now) noexcept {
    if (error_[index(dev)]) return;
    error_[index(dev)] = true;
    Event e = event(EventKind::DEVICE_ERROR, dev, now);
    e.detail.append(why.view());
    events_.push(e);
  }
  void good(Dev dev) noexcept { error_[index(dev)] = false; }

  /// Runs the detectors on a sensor's first value.
  void detect(Dev dev, Role r, Fixed v, Millis now) noexcept {
    if (r == Role::touch && touch_.update(v.raw == 1, now)) {
      events_.push(event(EventKind::OBSTACLE_DETECTED, dev, now));
    } else if (r == Role::ultrasonic && in_cm(body_.sensors[Body::in_index(dev)]) && proximity_.update(v)) {
      Event e = event(EventKind::PROXIMITY_ALERT, dev, now);
      e.detail.append_fixed(v.raw, v.decimals);
      events_.push(e);
    }
  }

  /// The one consumer of the event queue: critical events first (the queue's order), each handled
  /// (motors stopped where it says so), then handed on through poll_event().
  void pump(Millis now) noexcept {
    Event e;
    while (events_.pop(e)) {
      Ctx c = ctx(now);
      switch (e.kind) {
        case EventKind::BATTERY_LOW:
          if (runner_.active())
            runner_.halt(c, cfg_.tuning.pause_stop);
          else
            stop_all(c);
          leave_behaviour();
          off_ = true;
          break;
        case EventKind::DEVICE_DISCONNECTED:
          if (runner_.active() && needs_device(e.dev)) runner_.halt(c, cfg_.tuning.pause_stop);
          break;
        default: {
          const Outcome o = runner_.event(e, c);
          if (o == Outcome::interrupted) {
            e.interrupted = true;  // the link sends no EVENT for it when the core sent ACTION_INTERR
            outcome(o, now);
          }
          break;
        }
      }
      out_events_.push(e);
    }
  }

  /// Whether the running plan needs the device on @p dev (its motors, the sensors whose events
  /// interrupt it, the sensors it reads).
  bool needs_device(Dev dev) const noexcept {
    const action::Step& s = runner_.step();
    Role r{};
    if (cfg_.ports.role_on(dev, r)) {
      if (r == Role::left || r == Role::right) return s.kind != action::Kind::wait;
      if (r == Role::touch && contains(s.interrupts, EventKind::OBSTACLE_DETECTED)) return true;
      if (r == Role::ultrasonic && contains(s.interrupts, EventKind::PROXIMITY_ALERT)) return true;
    }
    return is_in_port(dev) && s.kind == action::Kind::pause && (s.sensors & (1u << Body::in_index(dev))) != 0;
  }

  void stop_all(Ctx& c) noexcept {
    ReasonText ignored;
    for (std::size_t w = 0; w < 2; ++w)
      if (body_.motor(w).present()) body_.motor(w).apply(Stop{cfg_.tuning.pause_stop}, c.writes, ignored);
  }

  void fail_running(const ReasonText& why, Millis now) noexcept {
    Ctx c = ctx(now);
    runner_.halt(c, cfg_.tuning.pause_stop);
    failed(why);
  }

  void failed(const ReasonText& why) noexcept {
    ActionResult r;
    r.outcome = Outcome::failed;
    r.detail = why;
    push_result(r);
  }

  void result(Outcome o) noexcept {
    if (o == Outcome::running) return;
    ActionResult r;
    r.outcome = o;
    r.detail = runner_.detail();
    r.warning = runner_.cause() == EventKind::PROXIMITY_ALERT ? Warning::PROXIMITY_ALERT : Warning::OBSTACLE_DETECTED;
    push_result(r);
  }

  void push_result(const ActionResult& r) noexcept { results_.push_over(r); }  // drained after every call

  // ------------------------------------------------------------------ behaviours (the automaton)

  /// Parses, sets the arguments of and checks behaviour @p name (a built-in, or `custom` with the
  /// definition in args[0]) into @p def; false with the reason.
  static bool resolve(std::string_view name, const std::string_view* args, std::size_t n, behaviour::Definition& def,
                      ReasonText& why) noexcept {
    namespace bhv = behaviour;
    char buf[bhv::kMaxMessage + 64];
    bhv::Text t(buf, sizeof buf);
    if (bhv::resolve_request(name, args, n, bhv::kModelA, bhv::kModelA.devices, def, t)) return true;
    why.append(t.view());
    return false;
  }

  /// Loads behaviour @p name with @p args into the automaton: parsed and checked again (as on
  /// receipt) into the scratch Definition, which the automaton copies; false with the reason.
  bool load_behaviour(std::string_view name, const std::string_view* args, std::size_t n, ReasonText& why) noexcept {
    namespace bhv = behaviour;
    if (!resolve(name, args, n, scratch_, why)) return false;
    std::uint8_t ports[bhv::kSensorCount] = {};
    for (std::size_t i = 0; i < bhv::kSensorCount; ++i) {
      Role r{};
      const Dev d_ = role_of(static_cast<bhv::Sensor>(i), r) ? cfg_.ports.of(r) : Dev::outA;
      if (is_in_port(d_)) ports[i] = static_cast<std::uint8_t>(1u << Body::in_index(d_));
    }
    auto_.load(scratch_, ports);
    return true;
  }

  /// The role of the device a behaviour sensor is read from (false: model A has none, the gyro).
  static bool role_of(behaviour::Sensor s, Role& r) noexcept {
    switch (s) {
      case behaviour::Sensor::distance: r = Role::ultrasonic; return true;
      case behaviour::Sensor::touch: r = Role::touch; return true;
      case behaviour::Sensor::colour: r = Role::colour; return true;
      case behaviour::Sensor::gyro: return false;
    }
    return false;
  }

  /// The last good reading of sensor @p s in the language's base units (distance mm, touch 0/1,
  /// colour code, gyro degrees).
  behaviour::Reading reading_of(behaviour::Sensor s) const noexcept {
    behaviour::Reading out;
    Role r{};
    if (!role_of(s, r)) return out;
    const Dev d = cfg_.ports.of(r);
    if (!is_in_port(d) || !attached_[index(d)]) return out;
    const SensorReadings& rd = body_.readings[Body::in_index(d)];
    if (!rd.valid || rd.info_stale || rd.count == 0) return out;
    std::int64_t v = rd.values[0].raw;
    if (s == behaviour::Sensor::distance) {  // cm with its decimals -> mm
      if (!in_cm(body_.sensors[Body::in_index(d)])) return out;
      v *= 10;
      for (std::uint8_t k = 0; k < rd.values[0].decimals; ++k) v /= 10;
    }
    out.valid = true;
    out.value = static_cast<std::int32_t>(v);
    return out;
  }

  /// The input ports the running behaviour's conditions and reports read each tick.
  std::uint8_t behaviour_ports() const noexcept {
    if (!behaviour_) return 0;
    const std::uint8_t m = auto_.sensors_read();
    std::uint8_t ports = 0;
    for (std::size_t i = 0; i < behaviour::kSensorCount; ++i) {
      Role r{};
      if ((m & (1u << i)) == 0 || !role_of(static_cast<behaviour::Sensor>(i), r)) continue;
      const Dev d = cfg_.ports.of(r);
      if (is_in_port(d) && attached_[index(d)]) ports = static_cast<std::uint8_t>(ports | (1u << Body::in_index(d)));
    }
    return ports;
  }

  /// The behaviour is over (stopped, replaced, or a plan run directly): its outputs are dropped.
  void leave_behaviour() noexcept {
    held_ = false;  // what was held is gone
    if (!behaviour_) return;
    behaviour_ = false;
    auto_.stop();
    for (behaviour::Output o; auto_.poll(o);) {
    }
  }

  /// Starts @p plan on the runner (a plan whose first step commands the motors takes over from the
  /// running one: a Stop coast after a RunForever must coast, not brake first; a plan that starts
  /// with a Wait stops them).
  Outcome start_plan(const action::Plan& plan, Millis now) noexcept {
    Ctx c = ctx(now);
    const bool takes_over = plan.count > 0 && plan.steps[0].kind != action::Kind::wait;
    if (takes_over)
      runner_.drop();
    else
      runner_.halt(c, cfg_.tuning.pause_stop);
    next_tick_ = now;
    if (off_) return Outcome::running;
    return runner_.start(plan, c);
  }

  /// An outcome of the runner: to the automaton when a behaviour runs, else a result as it is.
  void outcome(Outcome o, Millis now) noexcept {
    if (!behaviour_) return result(o);
    switch (o) {
      case Outcome::running: return;
      case Outcome::finished: auto_.finished(); break;
      case Outcome::failed: auto_.failed(); break;
      case Outcome::interrupted:
        if (!auto_.event(runner_.cause())) auto_.failed();
        break;
    }
    follow(now);
  }

  /// Carries out the automaton's outputs, in order (a plan that ends at once feeds it again).
  void follow(Millis now) noexcept {
    if (!behaviour_) return;
    Ctx c = ctx(now);
    for (behaviour::Output o; auto_.poll(o);) {
      switch (o.kind) {
        case behaviour::Output::Kind::start: {
          const Outcome r = start_plan(auto_.plan(), now);
          if (r == Outcome::finished) auto_.finished();
          else if (r == Outcome::failed) auto_.failed();
          break;
        }
        case behaviour::Output::Kind::pause: runner_.pause(c); break;
        case behaviour::Output::Kind::resume: {
          const Outcome r = runner_.resume(c);
          if (r == Outcome::failed) auto_.failed();
          break;
        }
        case behaviour::Output::Kind::halt:
        case behaviour::Output::Kind::done: runner_.halt(c, o.stop); break;
        case behaviour::Output::Kind::ok: result(Outcome::finished); break;
        case behaviour::Output::Kind::interrupted: {
          ActionResult r;
          r.outcome = Outcome::interrupted;
          r.detail = runner_.detail();
          r.warning = o.event == EventKind::PROXIMITY_ALERT ? Warning::PROXIMITY_ALERT : Warning::OBSTACLE_DETECTED;
          push_result(r);
          break;
        }
        case behaviour::Output::Kind::error: result(Outcome::failed); break;
        case behaviour::Output::Kind::report: report(o.sensor); break;
      }
    }
    next_tick_ = now < next_tick_ ? now : next_tick_;
  }

  /// Odometry from this tick's wheel positions; while the robot works (an action or a behaviour
  /// runs, not paused), its pose every pose_ms when it moved.
  void dead_reckon(Millis now) noexcept {
    if (!body_.left_pos.valid || !body_.right_pos.valid) return;  // a wheel missing or not read yet
    odometry_.update(body_.left_pos.position, body_.right_pos.position,
                     mm_per_count(cfg_.geo, body_.left.info().count_per_rot),
                     mm_per_count(cfg_.geo, body_.right.info().count_per_rot), cfg_.geo);
    if (cfg_.pose_ms == 0 || now < next_pose_ || !(runner_.active() || behaviour_) || runner_.paused()) return;
    next_pose_ = now + cfg_.pose_ms;
    if (!odometry_.report_due()) return;
    const Pose& p = odometry_.pose();
    Report rep;
    rep.odometry = true;
    rep.mode = ModeName("ODOM");
    rep.count = 3;
    rep.values[0] = Fixed{mm_clamped(p.x_mm), 0};
    rep.values[1] = Fixed{mm_clamped(p.y_mm), 0};
    rep.values[2] = Fixed{static_cast<std::int32_t>(std::lround(p.heading_deg * 10.0)) % 3600, 1};
    reports_.push(rep);
  }

  /// A coordinate in whole millimetres, within +-1000 km (a pose beyond is nonsense from garbage
  /// positions; it is reported at the bound, never overflowing).
  static std::int32_t mm_clamped(double mm) noexcept {
    constexpr double kBound = 1e9;
    return static_cast<std::int32_t>(std::lround(mm < -kBound ? -kBound : mm > kBound ? kBound : mm));
  }

  /// SENSOR_VALUE of behaviour sensor @p s: its last good reading, all its values.
  void report(behaviour::Sensor s) noexcept {
    Role r{};
    if (!role_of(s, r)) return;
    const Dev d = cfg_.ports.of(r);
    if (!is_in_port(d) || !attached_[index(d)]) return;
    const std::size_t i = Body::in_index(d);
    const SensorReadings& rd = body_.readings[i];
    if (!rd.valid || rd.info_stale) return;
    Report rep;
    rep.port = d;
    rep.mode = ModeName(body_.sensors[i].info().mode_name());
    rep.count = rd.count;
    for (std::size_t k = 0; k < rd.count; ++k) rep.values[k] = rd.values[k];
    reports_.push(rep);
  }

  struct Pending {
    Text<24> mode, decimals, num_values, units;
    unsigned got = 0;
  };

  RuntimeConfig cfg_;
  Body body_;
  ActionRunner runner_;
  Writes writes_;
  Reports reports_;
  EventQueue<16> events_;      ///< the one queue the producers push to
  EventQueue<16> out_events_;  ///< handled, for the agent core and the master
  TouchEdge touch_;
  ProximityWatch proximity_;
  BatteryWatch battery_watch_;
  bool attached_[kDevCount] = {};
  bool error_[kDevCount] = {};
  Pending pending_[4];
  Millis mode_retry_at_[4] = {};
  std::int32_t led_max_[kLedCount] = {};
  bool battery_ = false;
  bool off_ = false;
  std::uint32_t plugged_ = 0;
  Millis next_tick_ = 0, next_battery_ = 0;
  Ring<ActionResult, 4> results_;
  behaviour::Definition scratch_;  ///< where a behaviour is parsed and checked (on receipt, at START)
  behaviour::Automaton auto_;
  bool behaviour_ = false;         ///< the automaton drives the runner (a behaviour was started)
  Odometry odometry_;              ///< the pose from the wheels' positions
  Millis next_pose_ = 0;           ///< the next pose report is due then
  bool armed_ = false;             ///< the contact watchdog is armed (contact() was called)
  bool held_ = false;              ///< the watchdog holds the wheels
  std::uint32_t holds_ = 0;        ///< times it did
  Millis contact_ = 0;             ///< the last contact with a master
};

}  // namespace ev3proto::robot
