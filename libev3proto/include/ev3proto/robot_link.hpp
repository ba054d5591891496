/// @file robot_link.hpp
/// @brief Between a robot node (node.hpp: the agent core, and the Master core while elected) and
///        the robot runtime (robot_runtime.hpp): what each output of one is as an input of the
///        other. Sans-I/O like both; the agent program (agent/main.cpp) only moves bytes around it.
///
///  node -> runtime   LED pattern -> led(); behaviour control (start, pause, resume, stop,
///                    restart) -> control() with the loaded behaviour's name and arguments. The
///                    core pauses when it loses the master (WORKING -> PAUSED) and stops when it
///                    panics, so while the master is lost the motors are stopped, whatever the
///                    action was doing, within the call that delivers the core's event.
///  node -> runtime   the time the agent core last heard a master -> contact() (the runtime's
///                    contact watchdog holds turning wheels watchdog_ms after it).
///  runtime -> node   action results -> action_ok / action_interrupted(warning) / action_failed;
///                    events, each with the port from the device layer's address:
///                    DEVICE_DISCONNECTED -> device_unplugged(bits, port), DEVICE_CONNECTED ->
///                    device_plugged(bits, port), BATTERY_LOW -> battery_low, and what those do
///                    not take (a device the model does not use, one more while another is
///                    missing, the first of several back) and OBSTACLE_DETECTED / PROXIMITY_ALERT
///                    -> robot_event(name, port) (spec RobotEvent, while synced), except a warning
///                    that interrupted the running action: that one the core sent as
///                    ACTION_INTERR (docs/devices.md "Events"). DEVICE_ERROR is logged only.
///                    Sensor reports -> sensor_report.
///  capabilities      the devices the agent announces (announced_devices()). The core learns
///                    which of them are missing when the agent first syncs (ACTIVE): then it
///                    tells the master (EVENT DEVICE_DISCONNECTED) and refuses BEHAVIOUR ("missing
///                    device", the spec's devOk) until all are back. Before that there is no master
///                    to tell, and no BEHAVIOUR can come.
///  the check         the agent core asks the runtime about every BEHAVIOUR before it answers
///                    (behaviour_check(): AgentConfig::check -> Runtime::check_behaviour): a
///                    request that does not parse or check, or needs a device or an action model A
///                    lacks, gets NOT with the runtime's reason (`line 4 col 12: unknown action
///                    'trun' (...)`); the START that follows an ACK runs that request (parsed again).
///
/// exchange() runs both directions until neither has anything left: a call into the node can give
/// a control for the runtime (action_interrupted pauses it), a call into the runtime a result for
/// the node (a start with a bad argument fails at once).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "node.hpp"
#include "robot_runtime.hpp"

namespace ev3proto::robot {

/// The model devices an agent announces (Capabilities::devices): model A's on an ev3dev tree (the
/// device layer found ev3dev's device classes: a brick, or ev3-sim), none elsewhere (a PC without
/// ev3dev: only behaviours that need no device, `wait`, can run).
constexpr std::uint32_t announced_devices(bool ev3dev_tree) noexcept { return ev3dev_tree ? kModelADevices : 0; }

/// The robot's check of a BEHAVIOUR on receipt, for the agent core (AgentConfig::check):
/// Runtime::check_behaviour() of @p rt, its reason cut to CheckReason's bound. @p rt must outlive
/// the node.
inline BehaviourCheck behaviour_check(Runtime& rt) noexcept {
  BehaviourCheck c;
  c.ctx = &rt;
  c.fn = [](void* ctx, std::string_view name, const std::string_view* params, std::size_t count,
            CheckReason& why) noexcept {
    ReasonText r;
    const bool ok = static_cast<Runtime*>(ctx)->check_behaviour(name, params, count, r);
    if (!ok) why.set(r.view());
    return ok;
  };
  return c;
}

/// What the link handed on, for the program's log.
struct LinkNote {
  enum class Kind : std::uint8_t {
    result,   ///< an action result (result), taken by the core or not (taken)
    event,    ///< a robot event (event); taken: the core took it as a spec action (it tells the master)
    report,   ///< a sensor report (report)
    missing,  ///< after the first scan: model devices not found (bits)
    control,  ///< a behaviour control given to the runtime (control, name)
    watchdog, ///< the runtime's contact watchdog began (taken) or ended (!taken) a hold
  } kind = Kind::result;
  bool taken = false;
  ActionResult result;
  Event event;
  Report report;
  std::uint32_t bits = 0;
  ControlKind control = ControlKind::stop;
  std::string_view name;  ///< control: the behaviour (valid during the note)
};

/// The link of one node and one runtime (see the file comment). @tparam NodeT a Node<...>.
template <typename NodeT>
class RobotLink {
 public:
  /// @p announced: the devices the agent core was configured with (AgentConfig::caps.devices).
  explicit RobotLink(std::uint32_t announced) noexcept : announced_(announced) {}

  /// Once the agent is synced for the first time: the announced devices the runtime has not got
  /// are unplugged for the core (spec DeviceUnplugged: EVENT DEVICE_DISCONNECTED with the first
  /// one's port), and the master hears each other one's port too (RobotEvent: one more gone while
  /// another is missing), so that it knows every device missing. exchange() calls it; until then
  /// plug and unplug events are not the core's.
  template <typename Note>
  void report_missing(NodeT& node, const Runtime& rt, Millis now, Note&& note) {
    if (reported_ || !is_synced(node.agent().state())) return;
    reported_ = true;
    const std::uint32_t missing = announced_ & ~rt.plugged();
    if (missing == 0) return;
    bool first = true;
    for (std::size_t i = 0; i < kRoleCount; ++i) {
      const std::uint32_t bit = role_bit(static_cast<Role>(i));
      if ((missing & bit) == 0) continue;
      const Dev port = rt.ports().of(static_cast<Role>(i));
      LinkNote n;
      if (first) {  // DeviceUnplugged for all of them, told with this one's port
        n.kind = LinkNote::Kind::missing;
        n.bits = missing;
        n.taken = node.device_unplugged(missing, to_string(port), now);
        first = false;
      } else {
        n.kind = LinkNote::Kind::event;
        n.event.kind = EventKind::DEVICE_DISCONNECTED;
        n.event.dev = port;
        n.event.bits = bit;
        n.taken = node.robot_event(RobotEventKind::DEVICE_DISCONNECTED, to_string(port), now);
      }
      note(n);
    }
  }

  /// A node event for the robot: the LED pattern and behaviour controls go to the runtime; other
  /// kinds are the program's. Returns true when it was the runtime's.
  template <typename Note>
  bool on_node_event(const NodeEvent& e, const NodeT& node, Runtime& rt, Millis now, Note&& note) {
    if (e.kind == NodeEvent::Kind::led) {
      rt.led(e.led);
      return true;
    }
    if (e.kind != NodeEvent::Kind::control) return false;
    const auto b = node.agent().behaviour();
    std::string_view args[kMaxParams];
    std::size_t n = 0;
    for (; n < b.arg_count && n < kMaxParams; ++n) args[n] = b.arg(n);
    LinkNote ln;
    ln.kind = LinkNote::Kind::control;
    ln.control = e.control;
    ln.name = b.name;
    note(ln);
    rt.control(e.control, b.name, args, n, now);
    return true;
  }

  /// Hands the runtime's results, events and reports to the node, in that order.
  template <typename Note>
  void drain(Runtime& rt, NodeT& node, Millis now, Note&& note) {
    LinkNote n;
    n.kind = LinkNote::Kind::result;
    std::size_t interrupts = 0;  // interruptions the core took (ACTION_INTERR sent) in this drain
    while (rt.poll_result(n.result)) {
      switch (n.result.outcome) {
        case Outcome::finished: n.taken = node.action_ok(now); break;
        case Outcome::interrupted:
          n.taken = node.action_interrupted(n.result.warning, now);
          if (n.taken) ++interrupts;
          break;
        default: n.taken = node.action_failed(n.result.detail.view(), now); break;
      }
      note(n);
    }
    n.kind = LinkNote::Kind::event;
    while (rt.poll_event(n.event)) {
      const Event& e = n.event;
      const std::string_view port = is_port(e.dev) ? to_string(e.dev) : std::string_view{};
      const std::uint32_t bits = e.bits & announced_;
      n.taken = false;
      switch (e.kind) {
        // Before the first sync report_missing() says what is missing (and there is no master).
        case EventKind::DEVICE_DISCONNECTED:
          if (!reported_) break;
          if (bits != 0) n.taken = node.device_unplugged(bits, port, now);
          if (!n.taken) n.taken = node.robot_event(RobotEventKind::DEVICE_DISCONNECTED, port, now);
          break;
        case EventKind::DEVICE_CONNECTED:
          if (!reported_) break;
          if (bits != 0) n.taken = node.device_plugged(bits, port, now);
          if (!n.taken) n.taken = node.robot_event(RobotEventKind::DEVICE_CONNECTED, port, now);
          break;
        case EventKind::BATTERY_LOW: n.taken = node.battery_low(now); break;
        case EventKind::OBSTACLE_DETECTED:
        case EventKind::PROXIMITY_ALERT:
          if (e.interrupted && interrupts > 0) {
            --interrupts;  // the master heard it as ACTION_INTERR: one report per event
            break;
          }
          n.taken = node.robot_event(e.kind == EventKind::OBSTACLE_DETECTED ? RobotEventKind::OBSTACLE_DETECTED
                                                                            : RobotEventKind::PROXIMITY_ALERT,
                                     port, now);
          break;
        default: break;  // DEVICE_ERROR: the program's log
      }
      note(n);
    }
    n.kind = LinkNote::Kind::report;
    while (rt.poll_report(n.report)) {
      const Report& r = n.report;
      Text<24> texts[kMaxValues];
      std::string_view values[kMaxValues];
      const std::size_t count = r.count < kMaxValues ? r.count : kMaxValues;
      for (std::size_t i = 0; i < count; ++i) {
        texts[i].append_fixed(r.values[i].raw, r.values[i].decimals);
        values[i] = texts[i].view();
      }
      n.taken = node.sensor_report(report_port(r), r.mode.view(), values,
                                   count, now);
      note(n);
    }
  }

  /// The node's events (@p program gets those that are not the runtime's) and the runtime's
  /// outputs (@p write makes the device writes: the program's I/O), until neither has any left.
  template <typename Program, typename Write, typename Note>
  void exchange(NodeT& node, Runtime& rt, Millis now, Program&& program, Write&& write, Note&& note) {
    rt.contact(node.agent().last_heard());
    if (rt.held() != held_) {
      held_ = rt.held();
      LinkNote n;
      n.kind = LinkNote::Kind::watchdog;
      n.taken = held_;
      note(n);
    }
    for (int round = 0; round < 16; ++round) {
      bool any = false;
      NodeEvent e;
      while (node.poll_event(e)) {
        any = true;
        if (!on_node_event(e, node, rt, now, note)) program(e);
      }
      write();
      if (drained_something(rt, node, now, note)) any = true;
      if (!reported_ && is_synced(node.agent().state())) {
        report_missing(node, rt, now, note);
        any = true;
      }
      if (!any) return;
    }
  }

  std::uint32_t announced() const noexcept { return announced_; }
  /// True once BATTERY_LOW went through both: the runtime stopped the motors and starts nothing,
  /// the core sent EVENT BATTERY_LOW and is OFF. The program exits cleanly then.
  static bool shut_down(const NodeT& node, const Runtime& rt) noexcept {
    return rt.off() && node.agent().state() == State::OFF;
  }

 private:
  template <typename Note>
  bool drained_something(Runtime& rt, NodeT& node, Millis now, Note&& note) {
    bool any = false;
    auto counting = [&](const LinkNote& n) {
      any = true;
      note(n);
    };
    drain(rt, node, now, counting);
    return any;
  }

  std::uint32_t announced_;
  bool reported_ = false;  ///< report_missing() done (the agent synced once)
  bool held_ = false;      ///< the watchdog hold last noted
};

}  // namespace ev3proto::robot
