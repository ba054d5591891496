/// @file core.hpp
/// @brief Types shared by the agent and master cores: states, LEDs, spec action names, the allowed
///        transition table, refusal reasons, peers and destinations, behaviour controls.
///
/// Everything here mirrors spec/tla/AgentLogic.tla (names and values are the spec's, so trace records
/// can be compared with TLC's states). No heap, no exceptions, no RTTI.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "messages.hpp"
#include "timers.hpp"

namespace ev3proto {

/// An agent's lifecycle state (AgentLogic `States`). OFF: shut down after BatteryLow.
enum class State : std::uint8_t { IDLE, ACTIVE, WORKING, PAUSED, PANIC, OFF };

/// Number of agent states.
inline constexpr std::size_t kStateCount = 6;

/// LED pattern (AgentLogic `LedOf`).
enum class Led : std::uint8_t { YELLOW_BLINK, GREEN_BLINK, GREEN, ORANGE, RED_BLINK, DARK };

/// What a WORKING agent waits for (AgentLogic `Waits`): nothing, CONTINUE, or RESTART.
enum class Wait : std::uint8_t { NONE, CONTINUE, RESTART };

/// The spec's name of a state ("WORKING").
constexpr std::string_view to_string(State s) noexcept {
  switch (s) {
    case State::IDLE: return "IDLE";
    case State::ACTIVE: return "ACTIVE";
    case State::WORKING: return "WORKING";
    case State::PAUSED: return "PAUSED";
    case State::PANIC: return "PANIC";
    case State::OFF: return "OFF";
  }
  return {};
}

/// The spec's name of a LED pattern ("GREEN_BLINK").
constexpr std::string_view to_string(Led l) noexcept {
  switch (l) {
    case Led::YELLOW_BLINK: return "YELLOW_BLINK";
    case Led::GREEN_BLINK: return "GREEN_BLINK";
    case Led::GREEN: return "GREEN";
    case Led::ORANGE: return "ORANGE";
    case Led::RED_BLINK: return "RED_BLINK";
    case Led::DARK: return "DARK";
  }
  return {};
}

/// The spec's name of a wait ("CONTINUE").
constexpr std::string_view to_string(Wait w) noexcept {
  switch (w) {
    case Wait::NONE: return "NONE";
    case Wait::CONTINUE: return "CONTINUE";
    case Wait::RESTART: return "RESTART";
  }
  return {};
}

/// The LED pattern of each state (AgentLogic `LedOf`).
constexpr Led led_of(State s) noexcept {
  switch (s) {
    case State::IDLE: return Led::YELLOW_BLINK;
    case State::ACTIVE: return Led::GREEN_BLINK;
    case State::WORKING: return Led::GREEN;
    case State::PAUSED: return Led::ORANGE;
    case State::PANIC: return Led::RED_BLINK;
    case State::OFF: return Led::DARK;
  }
  return Led::DARK;
}

/// The agent state a PING carries (the wire's AgentState: every state but OFF) as a core State.
constexpr State state_of(AgentState s) noexcept {
  switch (s) {
    case AgentState::IDLE: return State::IDLE;
    case AgentState::ACTIVE: return State::ACTIVE;
    case AgentState::WORKING: return State::WORKING;
    case AgentState::PAUSED: return State::PAUSED;
    case AgentState::PANIC: return State::PANIC;
  }
  return State::IDLE;
}

/// States that have a master (AgentLogic `Synced`).
constexpr bool is_synced(State s) noexcept {
  return s == State::ACTIVE || s == State::WORKING || s == State::PAUSED;
}
/// States without a master (AgentLogic `Masterless`).
constexpr bool is_masterless(State s) noexcept { return s == State::IDLE || s == State::PANIC; }

/// The wire spelling of a state reported in PING (OFF never sends a PING).
constexpr AgentState wire_state(State s) noexcept {
  switch (s) {
    case State::IDLE: return AgentState::IDLE;
    case State::ACTIVE: return AgentState::ACTIVE;
    case State::WORKING: return AgentState::WORKING;
    case State::PAUSED: return AgentState::PAUSED;
    default: return AgentState::PANIC;
  }
}

/// Agent ids a master assigns (docs/protocol.md "Ids", AgentLogic `AssignedIds`).
inline constexpr std::uint16_t kFirstAssignedId = 2;
/// Last assignable agent id.
inline constexpr std::uint16_t kLastAssignedId = 49999;
/// First temporary id an unsynced agent may draw (50000..65535).
inline constexpr std::uint16_t kFirstTempId = 50000;
/// The master's id.
inline constexpr std::uint16_t kMasterId = 1;
/// The broadcast receiver id.
inline constexpr std::uint16_t kBroadcastId = 0;

/// True for an id a master may assign (2..49999).
constexpr bool is_assigned_id(std::uint32_t id) noexcept {
  return id >= kFirstAssignedId && id <= kLastAssignedId;
}

/// The spec's actions (handler names). Agent actions first (AgentLogic `ActionNames`), then the
/// master's (Fleet.tla). Each has exactly one handler of the same name in the C++ cores.
enum class Action : std::uint8_t {
  // Agent, receive handlers (AgentLogic RecvNames).
  RecvMaster, RecvPong, RecvBehaviour, RecvStart, RecvStop, RecvPause, RecvResume, RecvStandby,
  RecvContinue, RecvRestart, RecvDuplicate, Ignore,
  // Agent, internal (AgentLogic InternalNames).
  Tick, SyncTimeout, HeartbeatLost, ActionOk, ActionInterrupted, ActionFailed, SensorReport,
  DeviceUnplugged, DevicePlugged, BatteryLow, RobotEvent,
  // Master (MasterLogic.tla, same names; MasterTick is one resend period).
  MasterSync, MasterAnswer, MasterPing, MasterTick, MasterCommand, MasterReport,
  // Relay and election (spec/tla/Election.tla), agent and master side. Election's Timeout is the
  // agent's HeartbeatLost; SendCommand is MasterCommand (its EPOCH_CMD / RELAY wrapping).
  RequestRelay, OfferRelay, HandleAccept, AcceptRelay, RelayDropped, StartElection, HandleElect,
  HandleVote, BecomeMaster, Heartbeat, HandleHeartbeat, HandleStale, Forward, ApplyCommand,
  GrantPreVote, HandlePreVote,
  // Master-side extensions the spec abstracts (docs/core.md): the route and the handover.
  MasterRoute, MasterHandover,
  // Membership (Election.tla section Membership): agent side, then the PC's.
  ShareMembers, LearnMembers, Reconfigure,
  // Agent-side extension the spec abstracts: the program's EVENT(LEAVING) as it exits (Agent::leaving).
  Leave,
  // Reliable reports (spec/tla/Reports.tla): the agent takes REPORT_ACK; a master takes REPORT or
  // REPORT_DROPPED and acknowledges in the same step (PCTake, then PCAck).
  TakeAck, PCTake,
};

/// Number of actions.
inline constexpr std::size_t kActionCount = static_cast<std::size_t>(Action::PCTake) + 1;

/// The spec's name of an action ("RecvStart").
constexpr std::string_view to_string(Action a) noexcept {
  constexpr std::string_view kNames[kActionCount] = {
      "RecvMaster", "RecvPong", "RecvBehaviour", "RecvStart", "RecvStop", "RecvPause",
      "RecvResume", "RecvStandby", "RecvContinue", "RecvRestart", "RecvDuplicate", "Ignore",
      "Tick", "SyncTimeout", "HeartbeatLost", "ActionOk", "ActionInterrupted", "ActionFailed",
      "SensorReport", "DeviceUnplugged", "DevicePlugged", "BatteryLow", "RobotEvent",
      "MasterSync", "MasterAnswer", "MasterPing", "MasterTick", "MasterCommand", "MasterReport",
      "RequestRelay", "OfferRelay", "HandleAccept", "AcceptRelay", "RelayDropped", "StartElection",
      "HandleElect", "HandleVote", "BecomeMaster", "Heartbeat", "HandleHeartbeat", "HandleStale",
      "Forward", "ApplyCommand", "GrantPreVote", "HandlePreVote", "MasterRoute", "MasterHandover",
      "ShareMembers", "LearnMembers", "Reconfigure", "Leave", "TakeAck", "PCTake"};
  const auto i = static_cast<std::size_t>(a);
  return i < kActionCount ? kNames[i] : std::string_view{};
}

/// The waits (WORKING's sub-state) a table row applies to: a bit per Wait value.
using WaitSet = std::uint8_t;
/// Every wait: the row does not depend on it.
inline constexpr WaitSet kAnyWait = 0b111;
/// Only wait @p w.
constexpr WaitSet only(Wait w) noexcept { return static_cast<WaitSet>(1u << static_cast<unsigned>(w)); }

/// One row of the state table: in state @c from (and, in WORKING, one of the waits @c waits) action
/// @c by is taken and leads to @c to (which may equal @c from).
struct Transition {
  State from;               ///< State before.
  State to;                 ///< State after.
  Action by;                ///< The action taking it.
  WaitSet waits = kAnyWait; ///< The waits it applies to (RecvContinue: only CONTINUE).
};

/// The allowed state changes (AgentLogic `AllowedTransitions`, brief sec. 2). A unit test checks it
/// equals the spec's set.
inline constexpr Transition kTransitions[] = {
    {State::IDLE, State::ACTIVE, Action::RecvMaster},
    {State::IDLE, State::PANIC, Action::SyncTimeout},
    {State::ACTIVE, State::WORKING, Action::RecvStart},
    {State::ACTIVE, State::PANIC, Action::HeartbeatLost},
    {State::WORKING, State::ACTIVE, Action::RecvStop},
    {State::WORKING, State::ACTIVE, Action::RecvStandby},
    {State::WORKING, State::PAUSED, Action::RecvPause},
    {State::WORKING, State::PAUSED, Action::HeartbeatLost},
    {State::PAUSED, State::WORKING, Action::RecvResume},
    {State::PAUSED, State::WORKING, Action::RecvStart},
    {State::PAUSED, State::ACTIVE, Action::RecvStop},
    {State::PAUSED, State::PANIC, Action::HeartbeatLost},
    {State::PANIC, State::ACTIVE, Action::RecvMaster},
    {State::WORKING, State::ACTIVE, Action::DeviceUnplugged},
    {State::PAUSED, State::ACTIVE, Action::DeviceUnplugged},
    {State::IDLE, State::OFF, Action::BatteryLow},
    {State::ACTIVE, State::OFF, Action::BatteryLow},
    {State::WORKING, State::OFF, Action::BatteryLow},
    {State::PAUSED, State::OFF, Action::BatteryLow},
    {State::PANIC, State::OFF, Action::BatteryLow},
};

/// Where an action is taken without a state change (AgentLogic's TransitionOk allows every action
/// to keep the state; these rows say in which states each one is enabled, or accepted: a command
/// with no row in either table is refused "wrong state"). The spec's conditions they encode:
/// RecvPong and RecvBehaviour while Synced, RecvStart also in WORKING, RecvContinue / RecvRestart
/// in WORKING waiting for them, the behaviour events while Running (WORKING, wait NONE), a device
/// change in any state but OFF, a robot event (RobotEvent) while Synced.
inline constexpr Transition kStays[] = {
    {State::ACTIVE, State::ACTIVE, Action::RecvPong},
    {State::WORKING, State::WORKING, Action::RecvPong},
    {State::PAUSED, State::PAUSED, Action::RecvPong},
    {State::ACTIVE, State::ACTIVE, Action::RecvBehaviour},
    {State::WORKING, State::WORKING, Action::RecvBehaviour},
    {State::PAUSED, State::PAUSED, Action::RecvBehaviour},
    {State::WORKING, State::WORKING, Action::RecvStart},
    {State::WORKING, State::WORKING, Action::RecvContinue, only(Wait::CONTINUE)},
    {State::WORKING, State::WORKING, Action::RecvRestart, only(Wait::RESTART)},
    {State::WORKING, State::WORKING, Action::ActionOk, only(Wait::NONE)},
    {State::WORKING, State::WORKING, Action::ActionInterrupted, only(Wait::NONE)},
    {State::WORKING, State::WORKING, Action::ActionFailed, only(Wait::NONE)},
    {State::WORKING, State::WORKING, Action::SensorReport, only(Wait::NONE)},
    {State::IDLE, State::IDLE, Action::DeviceUnplugged},
    {State::ACTIVE, State::ACTIVE, Action::DeviceUnplugged},
    {State::PANIC, State::PANIC, Action::DeviceUnplugged},
    {State::IDLE, State::IDLE, Action::DevicePlugged},
    {State::ACTIVE, State::ACTIVE, Action::DevicePlugged},
    {State::WORKING, State::WORKING, Action::DevicePlugged},
    {State::PAUSED, State::PAUSED, Action::DevicePlugged},
    {State::PANIC, State::PANIC, Action::DevicePlugged},
    {State::ACTIVE, State::ACTIVE, Action::RobotEvent},
    {State::WORKING, State::WORKING, Action::RobotEvent},
    {State::PAUSED, State::PAUSED, Action::RobotEvent},
};

/// The state changes Election.tla adds, refined to the core's states (its CANDIDATE and MASTER are
/// PANIC with an ElectionRole; docs/election.md sec. 5): relay accepted or a master's LEADER followed
/// (PANIC -> ACTIVE), the relay dropped us (ACTIVE / WORKING / PAUSED -> PANIC), the master changed
/// or a newer epoch seen while WORKING (-> PAUSED until the new master resumes it). The election's
/// guards are Election.tla's (election/agent.hpp); these rows give the state each change leads to.
inline constexpr Transition kElectionTransitions[] = {
    {State::PANIC, State::ACTIVE, Action::AcceptRelay},
    {State::PANIC, State::ACTIVE, Action::HandleHeartbeat},
    {State::WORKING, State::PAUSED, Action::HandleHeartbeat},
    {State::WORKING, State::PAUSED, Action::HandleElect},
    {State::WORKING, State::PAUSED, Action::HandleStale},
    {State::WORKING, State::PAUSED, Action::LearnMembers},
    {State::ACTIVE, State::PANIC, Action::RelayDropped},
    {State::WORKING, State::PANIC, Action::RelayDropped},
    {State::PAUSED, State::PANIC, Action::RelayDropped},
};

/// The state table's answer for one action: taken (leading to @c to) or refused (no row).
struct Next {
  bool allowed = false;    ///< A row exists: the action is taken.
  State to = State::OFF;   ///< The state it leads to (meaningful when allowed).
  /// True when allowed.
  constexpr explicit operator bool() const noexcept { return allowed; }
};

/// The state table as the guard: the row of kTransitions, kStays or kElectionTransitions for action
/// @p by in state @p from with wait @p wait, or refused when none has one.
constexpr Next next_state(State from, Action by, Wait wait = Wait::NONE) noexcept {
  const WaitSet w = only(wait);
  for (const Transition& t : kTransitions)
    if (t.from == from && t.by == by && (t.waits & w) != 0) return Next{true, t.to};
  for (const Transition& t : kStays)
    if (t.from == from && t.by == by && (t.waits & w) != 0) return Next{true, t.to};
  for (const Transition& t : kElectionTransitions)
    if (t.from == from && t.by == by && (t.waits & w) != 0) return Next{true, t.to};
  return Next{};
}

/// Why a received datagram changed nothing (the agent core's and the node's handle_datagram()).
/// The spellings are the programs' drop counter names (docs/programs.md).
enum class Ignored : std::uint8_t {
  no,                  ///< It was handled (a spec action took it).
  undecodable,         ///< It does not decode (the result carries the codec's reason and field).
  off,                 ///< The agent is OFF (after BatteryLow): it takes no step at all.
  misaddressed,        ///< Its receiver is neither this agent's id nor 0.
  own_broadcast,       ///< This agent's own broadcast, heard back.
  foreign_sender,      ///< Not from the master followed (another agent's broadcast, a stranger's
                       ///< command, an EPOCH_CMD that fails the fence).
  not_for_agent,       ///< From the master, but a type agents never take (ACK, PING, reports), or
                       ///< a master's own type (RELAY_ROUTE, HANDOVER).
  stale_epoch,         ///< A command of an older epoch than the agent's: answered EPOCH_STALE.
  election_off,        ///< A relay / election datagram while the election is off.
  ignored_in_state,    ///< No handler takes it in this state (spec Ignore; an Election rule's
                       ///< guard does not hold).
  stale_copy,          ///< A command or MASTER of the master below a msgid the dedupe window
                       ///< remembers from it (AgentLogic Stale): a copy that outlived its entry.
  for_the_master_core, ///< (Node) The agent core ignored it; the Master core this node runs took it.
};

/// The drop counter name of a reason ("misaddressed").
constexpr std::string_view to_string(Ignored i) noexcept {
  switch (i) {
    case Ignored::no: return "handled";
    case Ignored::undecodable: return "decode";
    case Ignored::off: return "off";
    case Ignored::misaddressed: return "misaddressed";
    case Ignored::own_broadcast: return "own_broadcast";
    case Ignored::not_for_agent: return "not_for_agent";
    case Ignored::foreign_sender: return "foreign_sender";
    case Ignored::stale_epoch: return "stale_epoch";
    case Ignored::election_off: return "election_off";
    case Ignored::ignored_in_state: return "ignored_in_state";
    case Ignored::stale_copy: return "stale_copy";
    case Ignored::for_the_master_core: return "for_the_master_core";
  }
  return {};
}

/// An agent's part in the election (Election.tla life CANDIDATE / MASTER; both are the core's PANIC).
enum class ElectionRole : std::uint8_t {
  none,      ///< Follower, or PANIC without standing.
  candidate, ///< Stands in its epoch (voted for itself, counts votes).
  master,    ///< Won its epoch: the program runs a Master core for it (docs/core.md).
};

/// Spelling of a role ("candidate").
constexpr std::string_view to_string(ElectionRole r) noexcept {
  switch (r) {
    case ElectionRole::none: return "none";
    case ElectionRole::candidate: return "candidate";
    case ElectionRole::master: return "master";
  }
  return {};
}

namespace detail {
/// Each (state, action, wait) has at most one row across the three tables, so next_state() is a
/// function and the order of the tables does not matter.
template <std::size_t A, std::size_t B>
constexpr bool disjoint(const Transition (&a)[A], const Transition (&b)[B], bool same) noexcept {
  for (std::size_t i = 0; i < A; ++i)
    for (std::size_t j = same ? i + 1 : 0; j < B; ++j)
      if (a[i].from == b[j].from && a[i].by == b[j].by && (a[i].waits & b[j].waits) != 0) return false;
  return true;
}
constexpr bool transitions_are_a_function() noexcept {
  return disjoint(kTransitions, kTransitions, true) && disjoint(kStays, kStays, true) &&
         disjoint(kElectionTransitions, kElectionTransitions, true) &&
         disjoint(kTransitions, kStays, false) && disjoint(kTransitions, kElectionTransitions, false) &&
         disjoint(kStays, kElectionTransitions, false);
}
static_assert(transitions_are_a_function(), "the state table has two rows for one (state, action, wait)");
}  // namespace detail

/// Why an agent refuses a command (AgentLogic `Reasons`), carried in NOT.
enum class Refusal : std::uint8_t { unknown_behaviour, missing_device, no_behaviour, wrong_state };

/// The spec's (and the wire's) spelling of a refusal ("wrong state").
constexpr std::string_view to_string(Refusal r) noexcept {
  switch (r) {
    case Refusal::unknown_behaviour: return "unknown behaviour";
    case Refusal::missing_device: return "missing device";
    case Refusal::no_behaviour: return "no behaviour";
    case Refusal::wrong_state: return "wrong state";
  }
  return {};
}

/// Warning events that may interrupt a running action (AgentLogic `Warnings`).
enum class Warning : std::uint8_t { OBSTACLE_DETECTED, PROXIMITY_ALERT };

/// The spec's spelling of a warning.
constexpr std::string_view to_string(Warning w) noexcept {
  return w == Warning::OBSTACLE_DETECTED ? "OBSTACLE_DETECTED" : "PROXIMITY_ALERT";
}

/// The robot events a synced agent reports as EVENT(name, port) without a state change (AgentLogic
/// `RobotEvents`, spec RobotEvent): the warnings outside a running action, a device connected or
/// unplugged that DevicePlugged / DeviceUnplugged do not take.
enum class RobotEventKind : std::uint8_t { OBSTACLE_DETECTED, PROXIMITY_ALERT, DEVICE_CONNECTED, DEVICE_DISCONNECTED };

/// The spec's (and EVENT's) spelling of a robot event.
constexpr std::string_view to_string(RobotEventKind k) noexcept {
  switch (k) {
    case RobotEventKind::OBSTACLE_DETECTED: return "OBSTACLE_DETECTED";
    case RobotEventKind::PROXIMITY_ALERT: return "PROXIMITY_ALERT";
    case RobotEventKind::DEVICE_CONNECTED: return "DEVICE_CONNECTED";
    case RobotEventKind::DEVICE_DISCONNECTED: return "DEVICE_DISCONNECTED";
  }
  return {};
}

/// The robot event named @p name (false when it is none of them).
constexpr bool parse_robot_event(std::string_view name, RobotEventKind& out) noexcept {
  for (auto k : {RobotEventKind::OBSTACLE_DETECTED, RobotEventKind::PROXIMITY_ALERT, RobotEventKind::DEVICE_CONNECTED,
                 RobotEventKind::DEVICE_DISCONNECTED})
    if (to_string(k) == name) {
      out = k;
      return true;
    }
  return false;
}

/// True for the name of one of the EV3's eight ports (AgentLogic `Ports`): EVENT's second param for
/// a device's event.
constexpr bool is_port_name(std::string_view p) noexcept {
  constexpr std::string_view kPorts[] = {"in1", "in2", "in3", "in4", "outA", "outB", "outC", "outD"};
  for (std::string_view k : kPorts)
    if (k == p) return true;
  return false;
}

/// An opaque network peer handle: the program maps it to a socket address. 0 means "none".
using Peer = std::uint32_t;

/// Where a datagram goes.
enum class Dest : std::uint8_t {
  master,    ///< To the master (the peer the agent synced with).
  broadcast, ///< To everyone (UDP broadcast).
  peer,      ///< To one peer handle (the master's unicast to an agent).
};

/// Spelling of a destination in transcripts ("master").
constexpr std::string_view to_string(Dest d) noexcept {
  switch (d) {
    case Dest::master: return "master";
    case Dest::broadcast: return "broadcast";
    case Dest::peer: return "peer";
  }
  return {};
}

/// What the robot's behaviour runner must do (agent core output).
enum class ControlKind : std::uint8_t {
  start,   ///< Run the loaded behaviour (name, args) from its first action.
  pause,   ///< Stop the motors, keep the progress (resume continues).
  resume,  ///< Continue where it was paused.
  stop,    ///< Stop the motors and discard the progress.
  restart, ///< Run the same behaviour again from its first action (after ACTION_ERR).
};

/// Spelling of a control in transcripts ("start").
constexpr std::string_view to_string(ControlKind k) noexcept {
  switch (k) {
    case ControlKind::start: return "start";
    case ControlKind::pause: return "pause";
    case ControlKind::resume: return "resume";
    case ControlKind::stop: return "stop";
    case ControlKind::restart: return "restart";
  }
  return {};
}

/// A trace sink that records nothing: the default; every trace call compiles away.
struct NoTrace {
  /// False: the cores skip building trace records.
  static constexpr bool enabled = false;
};

}  // namespace ev3proto
