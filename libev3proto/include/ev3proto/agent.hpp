/// @file agent.hpp
/// @brief The agent (robot) protocol state machine of spec/tla/AgentLogic.tla, with no I/O.
///
/// Sans-I/O: the caller feeds received datagrams, the current monotonic time and device events in,
/// and drains datagrams to send, LED / state / behaviour-control events and the next deadline out.
/// No heap, no exceptions, no RTTI, no clocks, no globals, no randomness (the temporary id is drawn
/// by the caller). All memory is sized at compile time by the template parameters.
///
/// Every AgentLogic action has one handler of the same name (RecvMaster ... RobotEvent); Election.tla's
/// rules are election/agent.hpp's (AgentElection: variables, guards, transitions). A datagram enters
/// through one prelude (Step: the handler chosen first, epochs handled once), the state table is the
/// guard of every state change (an election transition's LifecycleEffect too), and the armed
/// deadlines are a TimerTable besides the election's two (docs/core.md).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "agent_outbox.hpp"
#include "agent_types.hpp"
#include "core.hpp"
#include "dedupe.hpp"
#include "election/agent.hpp"
#include "messages.hpp"
#include "msgids.hpp"
#include "reports.hpp"
#include "ring.hpp"
#include "timers.hpp"
#include "wire.hpp"

namespace ev3proto {

/// The agent core.
/// @tparam Trace trace sink: NoTrace (default, compiles to nothing) or a type with
///         `static constexpr bool enabled = true` and `template <class A> void record(const
///         AgentTraceRecord&, const A& agent)` (see trace.hpp).
/// @tparam Window dedupe window entries (spec Window; protocol default 50).
/// @tparam TxSlots datagrams that can wait in the output queue (the oldest is dropped when full).
/// @tparam TxBytes largest datagram the agent can send.
/// @tparam EventSlots events that can wait in the event queue (the oldest is dropped when full).
/// @tparam ArgBytes bytes for the loaded behaviour's arguments: by default as many as one datagram
///         carries, so that any `custom` definition that travels can be kept (explore's is 679
///         bytes in compact form; with 512 it was refused as "unknown behaviour").
/// @tparam RelaySlots agents one relay serves at once (and pending offers); Election relays.
/// @tparam ReportSlots reports kept until the PC acknowledges them (reports.hpp; the oldest are
///         dropped into the drop marker beyond it).
/// @tparam ReportBytes bytes for those reports (docs/reports.md sizes both for the EV3).
template <typename Trace = NoTrace, std::size_t Window = 50, std::size_t TxSlots = 8,
          std::size_t TxBytes = 512, std::size_t EventSlots = 16, std::size_t ArgBytes = kMaxDatagram,
          std::size_t RelaySlots = 4, std::size_t ReportSlots = kReportSlots, std::size_t ReportBytes = kReportBytes>
class Agent {
 public:
  /// Longest behaviour name the agent stores.
  static constexpr std::size_t kMaxNameLen = sizeof(AgentVars::beh);
  /// Most behaviour arguments (BEHAVIOUR has at most 31 besides the name).
  static constexpr std::size_t kMaxArgs = kMaxParams - 1;
  /// Bytes of an action's failure reason that ACTION_ERR carries (the rest is cut off).
  static constexpr std::size_t kMaxFailure = 96;
  /// "No deadline".
  static constexpr Millis kNever = ~Millis{0};
  /// The dedupe window type (payload: the recorded answer).
  using WindowType = DedupeWindow<Window, StoredAnswer>;
  /// The election part (Election.tla's variables, guards and transitions).
  using ElectionType = AgentElection<RelaySlots, kMaxMembership>;  // fleet members kept: kMaxMembership
  /// The loaded behaviour's storage.
  using BehaviourStore = LoadedBehaviour<kMaxNameLen, ArgBytes, kMaxArgs>;
  /// The reports not yet in the PC's record (Reports.tla).
  using ReportsType = ReportBuffer<ReportSlots, ReportBytes>;

  /// A fresh agent in IDLE at time @p now (spec Init with id = temp id).
  Agent(const AgentConfig& config, Millis now, Trace* trace = nullptr) noexcept
      : cfg_(config), trace_(trace), id_(config.temp_id), now_(now),
        heard_(now), plugged_(config.caps.devices), tx_(config.first_msgid), el_(config.election, config.timers), durable_(el_.durable()) {
    win_.set_limit(config.window);
    reports_.set_limit(config.report_limit);
    timers_.set(AgentTimer::periodic, now + cfg_.timers[Timer::heartbeat]);
    arm_lifecycle();
  }

  // ---------------------------------------------------------------- inputs

  /// Time moves to @p now: spec Ticks (periodic AGENT / PING / PANIC) and, before time moves past
  /// them, due timeouts (SyncTimeout, HeartbeatLost) and the election's timers. A @p now in the
  /// past changes nothing.
  void advance(Millis now) noexcept {
    if (state_ == State::OFF) {
      if (now > now_) now_ = now;
      return;
    }
    for (;;) {
      if (SyncTimeoutOk()) {
        traced(Action::SyncTimeout, [this] { SyncTimeout(); });
        continue;
      }
      if (HeartbeatLostOk()) {
        traced(Action::HeartbeatLost, [this] { HeartbeatLost(); });
        continue;
      }
      if (RequestRelayOk()) {
        traced(Action::RequestRelay, [this] { el_.RequestRelay(lifecycle(), *this); });
        continue;
      }
      if (StartElectionOk()) {
        traced(Action::StartElection, [this] {
          el_.StartElection(lifecycle(), *this);
          durable_changed();
        });
        continue;
      }
      if (BecomeMasterOk()) {
        traced(Action::BecomeMaster, [this] { BecomeMaster(); });
        continue;
      }
      const Millis due = next_due();
      const Millis target = due < now ? due : now;
      if (target <= now_) break;
      Tick(target);
    }
  }

  /// A datagram @p bytes arrived from @p from at @p now. Time advances first; the datagram is
  /// decoded (a failure is no spec step: counted in rejected(), the reason in the result), then
  /// handle_message(). Returns the action taken or why none was.
  Handled handle_datagram(std::string_view bytes, Peer from, Millis now) noexcept {
    advance(now);
    Handled h;
    h.decode = decode(bytes, rx_);
    if (!h.decode.ok()) {
      ++rejected_;
      h.why = Ignored::undecodable;
      return h;
    }
    return StepThenDue(rx_, bytes, from);
  }

  /// The decoded datagram @p m (its bytes @p bytes, for the trace) arrived from @p from at @p now:
  /// exactly one receive handler takes it (spec Handler, Election's rules), or none (the result says
  /// why). For a caller that decoded it already (Node): each datagram is decoded once.
  Handled handle_message(const Message& m, std::string_view bytes, Peer from, Millis now) noexcept {
    advance(now);
    return StepThenDue(m, bytes, from);
  }

  /// Step, then StartElection if the step made it due: a PREVOTE_OK or a membership learned can
  /// complete a quorum whose back-off is over, and the agent stands now (its next deadline is
  /// never left in the past).
  Handled StepThenDue(const Message& m, std::string_view bytes, Peer from) noexcept {
    const Handled h = Step(m, bytes, from);
    if (StartElectionOk()) advance(now_);
    return h;
  }

  /// The running action finished (spec ActionOk). Returns false (nothing done) unless Running.
  bool action_ok(Millis now) noexcept {
    advance(now);
    if (!ActionOkOk()) return false;
    traced(Action::ActionOk, [this] { ActionOk(); });
    return true;
  }

  /// A warning (obstacle, proximity) the behaviour cannot resolve (spec ActionInterrupted).
  /// Returns false (nothing done) unless Running: other warnings are not protocol-visible.
  bool action_interrupted(Warning w, Millis now) noexcept {
    advance(now);
    if (!ActionInterruptedOk()) return false;
    const AgentVars before = vars();
    ActionInterrupted(w);
    record(Action::ActionInterrupted, before, {}, to_string(w), 0);
    return true;
  }

  /// The running action failed for @p why, the robot's words ("outB stalled at -913 of -2046
  /// counts"; the first kMaxFailure bytes travel, "error" if it is empty) (spec ActionFailed).
  /// Returns false unless Running.
  bool action_failed(std::string_view why, Millis now) noexcept {
    advance(now);
    if (!ActionFailedOk()) return false;
    const std::string_view f = why.empty() ? std::string_view("error") : why.substr(0, kMaxFailure);
    const AgentVars before = vars();
    ActionFailed(f);
    record(Action::ActionFailed, before, {}, f, 0);
    return true;
  }

  /// A sensor reading the behaviour asked for (spec SensorReport): SENSOR_VALUE(port, mode,
  /// values...). Returns false unless Running, or if it has no value or does not fit a datagram.
  bool sensor_report(std::string_view port, std::string_view mode, const std::string_view* values,
                     std::size_t count, Millis now) noexcept {
    advance(now);
    if (!SensorReportOk() || count == 0 || count > kMaxParams - 2) return false;
    const AgentVars before = vars();
    if (!SensorReport(port, mode, values, count)) return false;
    record(Action::SensorReport, before, {}, {}, 0);
    return true;
  }

  /// Device bit(s) @p device were unplugged from @p port (one of the EV3's ports, is_port_name();
  /// otherwise nothing is done). The first unplug while all devices are present is the spec's
  /// DeviceUnplugged (EVENT DEVICE_DISCONNECTED, port); further unplugs only update the mask (the
  /// caller may report them with robot_event). Returns true if the spec action was taken.
  bool device_unplugged(std::uint32_t device, std::string_view port, Millis now) noexcept {
    advance(now);
    if (!is_port_name(port)) return false;
    if (!DeviceUnpluggedOk(port)) {
      plugged_ &= ~device;
      return false;
    }
    const AgentVars before = vars();
    plugged_ &= ~device;
    if (dev_ok()) return false;  // not a device of the model
    DeviceUnplugged(port);
    record(Action::DeviceUnplugged, before, {}, {}, 0, Action::Ignore, port);
    advance(now_);  // PAUSED -> ACTIVE: ACTIVE's shorter timeout may be due already (HeartbeatLost now)
    return true;
  }

  /// Device bit(s) @p device are back, on @p port (one of the EV3's ports; otherwise nothing is
  /// done). When that makes every device of the model present again it is the spec's DevicePlugged
  /// (EVENT DEVICE_CONNECTED, port). Returns true if the spec action was taken.
  bool device_plugged(std::uint32_t device, std::string_view port, Millis now) noexcept {
    advance(now);
    if (!is_port_name(port)) return false;
    const bool ok = DevicePluggedOk(port);
    const AgentVars before = vars();
    plugged_ |= device & cfg_.caps.devices;
    if (!ok || !dev_ok()) return false;  // still a device missing (or OFF)
    DevicePlugged(port);
    record(Action::DevicePlugged, before, {}, {}, 0, Action::Ignore, port);
    return true;
  }

  /// A robot event @p e about the device on @p port that changes no protocol state (spec
  /// RobotEvent): EVENT(name, port) to the master. Returns false (nothing done) unless Synced and
  /// @p port is one of the EV3's ports. The caller decides which events go here: an event that
  /// interrupted the running action is action_interrupted()'s (docs/devices.md "Events").
  bool robot_event(RobotEventKind e, std::string_view port, Millis now) noexcept {
    advance(now);
    if (!RobotEventOk(port)) return false;
    const AgentVars before = vars();
    RobotEvent(e, port);
    record(Action::RobotEvent, before, {}, to_string(e), 0, Action::Ignore, port);
    return true;
  }

  /// The battery is low (spec BatteryLow): tell the master, stop, shut down (OFF).
  bool battery_low(Millis now) noexcept {
    advance(now);
    if (!BatteryLowOk()) return false;
    traced(Action::BatteryLow, [this] { BatteryLow(); });
    return true;
  }

  /// The program is about to exit: EVENT(LEAVING) to the master, so it need not wait for the drop
  /// timeout (the protocol has no leave message; the master shows it as a report). Nothing else
  /// changes. Returns false (nothing sent) unless Synced and not OFF. Not a spec action: its trace
  /// record (Action::Leave) shows the msgid it used; the trace checks pass over it.
  bool leaving(Millis now) noexcept {
    advance(now);
    if (!is_synced(state_)) return false;
    const AgentVars before = vars();
    const std::string_view p[1] = {"LEAVING"};
    emit_from(id_, Dest::master, master_id(), MsgType::EVENT, p, 1);  // a goodbye, not a numbered report
    record(Action::Leave, before, {}, "LEAVING", 0);
    return true;
  }

  // ---------------------------------------------------------------- outputs

  /// Takes the oldest datagram to send; false when there is none.
  bool poll_transmit(Transmit& out) noexcept { return tx_.poll(out, master_peer_); }

  /// Takes the oldest event (state, LED, behaviour control); false when there is none.
  bool poll_event(AgentEvent& out) noexcept {
    return ev_.pop(out);
  }

  /// When the caller must call advance() next at the latest (kNever in OFF): the earliest armed
  /// timer.
  Millis next_deadline() const noexcept { return state_ == State::OFF ? kNever : next_due(); }

  // ---------------------------------------------------------------- observers

  /// Current state.
  State state() const noexcept { return state_; }
  /// Current LED pattern.
  Led led() const noexcept { return led_; }
  /// Current id (temporary until synced).
  std::uint16_t id() const noexcept { return id_; }
  /// True while the motors may run (spec motors = "ON").
  bool motors() const noexcept { return motors_; }
  /// What the running behaviour waits for.
  Wait wait() const noexcept { return wait_; }
  /// Index of the current action (spec step).
  std::uint32_t step() const noexcept { return step_; }
  /// True when every device of the model is plugged (spec devOk).
  bool dev_ok() const noexcept { return plugged_ == cfg_.caps.devices; }
  /// The loaded behaviour (name "" when none).
  BehaviourView behaviour() const noexcept {
    return beh_.view();
  }
  /// The agent's time (the latest now it was given).
  Millis now() const noexcept { return now_; }
  /// Time the master was last heard (a fresh command, MASTER or PONG).
  Millis last_heard() const noexcept { return heard_; }
  /// The dedupe window (read-only).
  const WindowType& window() const noexcept { return win_; }
  /// Datagrams that did not decode.
  std::uint32_t rejected() const noexcept { return rejected_; }
  /// The reports not yet in the PC's record (made, lo, mk, held, dropped: reports.hpp).
  const ReportsType& reports() const noexcept { return reports_; }
  /// msgid the next datagram will carry.
  std::uint32_t next_msgid() const noexcept { return tx_.next_msgid(); }
  /// Datagrams or events dropped because the caller did not drain the queues.
  std::uint32_t overflowed() const noexcept { return tx_.overflowed() + ev_overflowed_; }
  /// The armed deadline of timer @p t (kNever when stopped).
  Millis deadline(AgentTimer t) const noexcept {
    if (t == AgentTimer::relay) return el_.relay_at;
    if (t == AgentTimer::stand) return el_.StandDeadline(id_);
    return timers_.get(t);
  }

  // ------------------------------------------------------ election observers

  /// Election.tla's variables (read-only): role, epoch, leader, following, via, relays, offered,
  /// votes, prevotes, members, mepoch, floor, master_epoch (election/agent.hpp). With role ==
  /// master a Master core runs for master_epoch, seeded with the members (node.hpp).
  const ElectionType& election() const noexcept { return el_; }
  /// What to keep on stable storage (epoch, votedFor, members, mepoch, floor): write it when durable_rev() changed, before
  /// sending what the call that changed it queued (a VOTE must not outlive a lost votedFor).
  Durable durable() const noexcept { return el_.durable(); }
  /// Changes whenever durable() changes.
  std::uint32_t durable_rev() const noexcept { return durable_rev_; }
  /// The score this agent announces when it stands (ElectionConfig::score, or computed: 16 x the
  /// behaviours it can run now + the devices plugged; lower = weaker).
  std::uint32_t score() const noexcept {
    if (cfg_.election.score != kAutoScore) return cfg_.election.score;
    std::uint32_t runnable = 0, devices = 0;
    for (std::size_t i = 0; i < cfg_.caps.behaviour_count; ++i)
      runnable += (cfg_.caps.behaviours[i].devices & ~plugged_) == 0 ? 1u : 0u;
    for (std::uint32_t b = plugged_; b != 0; b &= b - 1) ++devices;
    return runnable * 16u + devices;
  }
  /// The spec variables now.
  AgentVars vars() const noexcept {
    AgentVars v;
    v.state = state_;
    v.led = led_;
    v.id = id_;
    const std::string_view beh = beh_.name();
    std::memcpy(v.beh, beh.data(), beh.size());
    v.beh_len = static_cast<std::uint8_t>(beh.size());
    v.step = step_;
    v.wait = wait_;
    v.motors = motors_;
    v.dev_ok = dev_ok();
    v.silence = silence();
    v.clk = (now_ - clk_origin()) % cfg_.timers[Timer::heartbeat];
    v.win_rev = win_rev_;
    v.election = el_.enabled;
    v.role = el_.role;
    v.epoch = el_.epoch;
    v.voted_for = el_.voted_for;
    v.leader = el_.leader;
    v.following = el_.following;
    v.via = el_.via;
    v.relay_rev = el_.sets_rev();
    v.mepoch = el_.mepoch;
    v.floor = el_.floor;
    v.members_rev = el_.members.rev();
    v.msgid = tx_.next_msgid();
    v.made = reports_.made();
    v.lo = reports_.lo();
    return v;
  }

  /// The receive handler the spec's Handler(a, m) picks for @p m from the master followed (at most
  /// one applies).
  Action Handler(const Message& m) const noexcept { return Handler(m, master_id()); }

 private:
  friend ElectionType;  // its transitions send through emit, emit_to, emit_raw

  // ------------------------------------------------------------ the Step prelude

  /// Every decoded datagram enters here (raft's Step): the handler that takes it is chosen before
  /// anything changes (Choose: the guards, the fence); a sender in an older epoch is answered
  /// EPOCH_STALE and nothing else happens; a newer epoch is adopted (stepping down) before the
  /// handler runs; then the handler; one trace record.
  Handled Step(const Message& m, std::string_view bytes, Peer from) noexcept {
    Handled h;
    if (state_ == State::OFF) {  // OFF takes no step at all (Agent.tla)
      h.why = Ignored::off;
      return h;
    }
    const AgentVars before = vars();
    const Message* inner = nullptr;
    if ((m.type == MsgType::RELAY || m.type == MsgType::EPOCH_CMD) && decode(m.param(1), inner_).ok())
      inner = &inner_;
    const Verdict v = Choose(m, inner);
    if (v.stale) {
      el_.AnswerStale(m.sender, from, *this);
    } else {
      if (v.epoch > el_.epoch) NewerEpoch(v.epoch, v.action);
      Run(v, m, inner, from);
      Send();  // a master found, or an acknowledgement that opens the window
    }
    record(v.action, before, bytes, {}, 0, v.inner);
    refused_now_ = false;
    if (v.action != Action::ShareMembers && !v.stale && el_.ShareMembersOk(m, lifecycle())) {
      // Election ShareMembers, besides OfferRelay / GrantPreVote on the same RELAY_REQ: a second step.
      const AgentVars b = vars();
      el_.ShareMembers(m, from, *this);
      record(Action::ShareMembers, b, bytes, {}, 0);
    }
    if (BecomeMasterOk()) traced(Action::BecomeMaster, [this] { BecomeMaster(); });
    h.action = v.action;
    h.why = v.why;
    h.inner = v.inner;
    return h;
  }

  /// Which handler takes @p m (@p inner: the datagram inside a RELAY / EPOCH_CMD, nullptr when it
  /// does not decode): relay / election types by Election's rules, EPOCH_CMD through the fence,
  /// a bare command after an election (epoch > 1) is stale, the rest by AgentLogic's Handler.
  Verdict Choose(const Message& m, const Message* inner) const noexcept {
    if (m.type == MsgType::REPORT_ACK) return TakeAckOk(m);
    if (m.type >= MsgType::RELAY_REQ && m.type <= MsgType::PREVOTE_OK) {
      if (!el_.enabled) return Verdict{Action::Ignore, Ignored::election_off};
      if (m.sender == id_) return Verdict{Action::Ignore, Ignored::own_broadcast};
      if (m.type == MsgType::EPOCH_CMD) return ApplyCommandOk(m, inner);
      return el_.Choose(m, inner, lifecycle());
    }
    if (el_.enabled && el_.epoch > 1 && Answered(m) && AddressedTo(m)) {
      // A bare command counts as epoch 1, older than ours: fenced, the sender learns our epoch.
      Verdict v{Action::Ignore, Ignored::stale_epoch};
      v.stale = true;
      return v;
    }
    return ChooseReceive(m, master_id());
  }

  /// AgentLogic's Handler for @p m from master @p master, with the reason when it is Ignore.
  Verdict ChooseReceive(const Message& m, std::uint16_t master) const noexcept {
    const Action a = Handler(m, master);
    if (a != Action::Ignore) return Verdict{a};
    if (!AddressedTo(m)) return Verdict{Action::Ignore, Ignored::misaddressed};
    if (m.sender != master) return Verdict{Action::Ignore, Ignored::foreign_sender};
    if (!Answered(m) && m.type != MsgType::PONG) return Verdict{Action::Ignore, Ignored::not_for_agent};
    if (Stale(m)) return Verdict{Action::Ignore, Ignored::stale_copy};
    return Verdict{Action::Ignore, Ignored::ignored_in_state};
  }

  /// Spec ApplyCommand's enabling condition, on the outer EPOCH_CMD(e, inner): the inner datagram
  /// decodes and is the sender's, e is an epoch (1 or more); e older than ours: stale. The master of epoch e syncs a
  /// masterless agent (MASTER inside), or commands the agent that follows it in e (Election Obeys).
  Verdict ApplyCommandOk(const Message& m, const Message* inner) const noexcept {
    const auto e = m.param_u32(0);
    if (!e || *e == 0 || inner == nullptr || inner->sender != m.sender || inner->type == MsgType::EPOCH_CMD ||
        inner->type == MsgType::RELAY)
      return Verdict{Action::Ignore, Ignored::ignored_in_state};
    Verdict v{Action::ApplyCommand};
    if (*e < el_.epoch) {  // no spec step (ApplyCommand is not enabled); answered EPOCH_STALE
      v = Verdict{Action::Ignore, Ignored::stale_epoch};
      v.stale = true;
      return v;
    }
    v.inner = Handler(*inner, m.sender);
    if (inner->type == MsgType::MASTER) {
      if (v.inner == Action::RecvMaster) v.epoch = *e;
      if (v.inner == Action::RecvMaster || v.inner == Action::RecvDuplicate) return v;
      return Verdict{Action::Ignore, Ignored::ignored_in_state};
    }
    if (!el_.Obeys(m.sender, *e)) return Verdict{Action::Ignore, Ignored::foreign_sender};
    return v;
  }

  /// Runs the handler @p v chose.
  void Run(const Verdict& v, const Message& m, const Message* inner, Peer from) noexcept {
    switch (v.action) {
      case Action::TakeAck: TakeAck(m); break;
      case Action::OfferRelay: el_.OfferRelay(m, from, *this); break;
      case Action::GrantPreVote: el_.GrantPreVote(m, from, lifecycle(), *this); break;
      case Action::HandlePreVote: el_.HandlePreVote(m); break;
      case Action::AcceptRelay: Apply(el_.AcceptRelay(m, from, *this), v.action, from); break;
      case Action::HandleAccept: el_.HandleAccept(m, from, *this); break;
      case Action::Forward: el_.Forward(m, *this); break;
      case Action::RelayDropped: Apply(el_.RelayDropped(m), v.action, from); break;
      case Action::HandleElect:
        el_.HandleElect(m, from, lifecycle(), *this);
        durable_changed();
        break;
      case Action::HandleVote: el_.HandleVote(m); break;
      case Action::HandleHeartbeat:
        Apply(el_.HandleHeartbeat(m, *this), v.action, from);
        durable_changed();
        break;
      case Action::HandleStale: el_.HandleStale(m); break;
      case Action::ShareMembers: el_.ShareMembers(m, from, *this); break;
      case Action::LearnMembers:
        el_.LearnMembers(m, lifecycle());
        durable_changed();
        break;
      case Action::ApplyCommand: ApplyCommand(v.inner, *inner, from, m.sender, *m.param_u32(0)); break;
      default: Receive(v.action, m, from, master_id(), 1); break;
    }
  }

  /// AgentLogic's Receive: the receive handler @p h on @p m from master @p master of epoch @p e.
  void Receive(Action h, const Message& m, Peer from, std::uint16_t master, std::uint32_t e) noexcept {
    switch (h) {
      case Action::RecvMaster: RecvMaster(m, from, master, e); break;
      case Action::RecvPong: RecvPong(m); break;
      case Action::RecvBehaviour:
      case Action::RecvStart:
      case Action::RecvStop:
      case Action::RecvPause:
      case Action::RecvResume:
      case Action::RecvStandby:
      case Action::RecvContinue:
      case Action::RecvRestart: ObeyCommand(h, m); break;
      case Action::RecvDuplicate: RecvDuplicate(m); break;
      default: Ignore(m); break;
    }
  }

  /// A fresh command from the master: the state table is the guard. With no row for the state
  /// (and wait) it is refused "wrong state"; otherwise its handler runs towards the row's state.
  void ObeyCommand(Action h, const Message& m) noexcept {
    const Next next = next_state(state_, h, wait_);
    if (!next) return Refuse(m, Refusal::wrong_state);
    switch (h) {
      case Action::RecvBehaviour: RecvBehaviour(m); break;
      case Action::RecvStart: RecvStart(m, next.to); break;
      case Action::RecvStop: RecvStop(m, next.to); break;
      case Action::RecvPause: RecvPause(m, next.to); break;
      case Action::RecvResume: RecvResume(m, next.to); break;
      case Action::RecvStandby: RecvStandby(m, next.to); break;
      case Action::RecvContinue: RecvContinue(m); break;
      case Action::RecvRestart: RecvRestart(m, next.to); break;
      default: break;
    }
  }

  /// A newer epoch than ours, seen in a datagram a handler takes: Election SteppedDown (a WORKING
  /// agent pauses; AgentElection::NewerEpoch: a master or candidate goes back to plain PANIC, nobody
  /// is followed any more), then the epoch is adopted with no vote and no pre-votes in it.
  void NewerEpoch(std::uint32_t e, Action by) noexcept {
    step_down(by);
    el_.NewerEpoch(e, lifecycle(), *this);
    durable_changed();
  }

  // ------------------------------------------------------------ lifecycle changes of the election

  /// Applies the lifecycle effect @p fx of election step @p by through the state table; @p from:
  /// the datagram's peer (where the master followed now is reached).
  void Apply(const LifecycleEffect& fx, Action by, Peer from) noexcept {
    if (fx.pause) step_down(by);
    if (fx.follow) {
      if (state_ == State::PANIC) {
        Goto(next_state(state_, by).to);
        reset_clk();
      }
      master_peer_ = from;
      hear();
    }
    if (fx.panic) enter_panic(by);
  }
  /// Follow master @p leader of epoch @p e, through relay @p via (0: directly) at peer @p peer
  /// (AgentElection::become_follower); the master counts as heard.
  void follow(std::uint16_t leader, std::uint32_t e, std::uint16_t via, Peer peer) noexcept {
    el_.become_follower(leader, e, via);
    master_peer_ = peer;
    hear();
    reports_.new_master();  // it has acknowledged nothing: everything held goes to it (Step's Send)
  }
  /// The lifecycle enters PANIC by action @p by (SyncTimeout, HeartbeatLost, RelayDropped): the
  /// behaviour stops, PANIC is broadcast at once (spec !.clk = 0), then the election's part
  /// (AgentElection::Panic: the master no longer followed, the relay table dropped with RELAY_DROP,
  /// relay requests and standing).
  void enter_panic(Action by) noexcept {
    Stopped();
    Goto(next_state(state_, by).to);
    hear();
    reset_clk();
    emit(Dest::broadcast, kBroadcastId, MsgType::PANIC, nullptr, 0);
    el_.Panic(lifecycle(), *this);
  }
  /// Election SteppedDown(n, s) by action @p by, the lifecycle's part: WORKING pauses (motors off,
  /// progress kept).
  void step_down(Action by) noexcept {
    if (state_ == State::WORKING) {
      Goto(next_state(state_, by).to);
      motors_pause();
    }
  }

  // ------------------------------------------------------------ spec helpers

  /// AgentLogic AddressedTo: to its id, to everyone, or a MASTER naming its id while masterless.
  bool AddressedTo(const Message& m) const noexcept {
    if (m.receiver == id_ || m.receiver == kBroadcastId) return true;
    return is_masterless(state_) && m.type == MsgType::MASTER && ref_of(m) == id_ &&
           is_assigned_id(m.receiver);
  }
  /// AgentLogic FromMaster, with @p master the sender a command must come from.
  bool FromMaster(const Message& m, std::uint16_t master) const noexcept {
    return state_ != State::OFF && m.sender == master && AddressedTo(m);
  }
  /// AgentLogic Seen: (src, msgid) in the window.
  bool Seen(const Message& m) const noexcept { return win_.contains(m.sender, m.msgid); }
  /// AgentLogic Stale: a command or MASTER below a msgid the window remembers from its sender -- a
  /// copy that outlived its own entry (the master's msgids increase and are never reused,
  /// docs/protocol.md "Duplicates"), so it was acted on already or given up by the master.
  /// "Below" is serial-number order (msgid_newer): msgids wrap at 2^32.
  bool Stale(const Message& m) const noexcept {
    if (!Answered(m)) return false;
    bool older = false;
    win_.for_each([&](std::uint16_t src, std::uint32_t msgid, const StoredAnswer&) {
      if (src == m.sender && msgid_newer(msgid, m.msgid)) older = true;
    });
    return older;
  }
  /// AgentLogic Fresh: (src, msgid) not in the window, and not stale.
  bool Fresh(const Message& m) const noexcept { return !Seen(m) && !Stale(m); }
  /// AgentLogic Answered: types answered with ACK / NOT.
  static bool Answered(const Message& m) noexcept {
    return m.type == MsgType::MASTER || (m.type >= MsgType::BEHAVIOUR && m.type <= MsgType::RESTART);
  }
  /// Messages.tla ref: the numeric first param of the RefTypes, else 0.
  static std::uint32_t ref_of(const Message& m) noexcept {
    switch (m.type) {
      case MsgType::MASTER:
      case MsgType::ACK:
      case MsgType::NOT:
      case MsgType::PONG:
      case MsgType::ACTION_OK:
      case MsgType::ACTION_INTERR:
      case MsgType::ACTION_ERR: return m.param_u32(0).value_or(0);
      default: return 0;
    }
  }
  /// The state table allows action @p a now (in this state and wait).
  bool Allowed(Action a) const noexcept { return static_cast<bool>(next_state(state_, a, wait_)); }
  /// Spec silence (0 in PANIC).
  Millis silence() const noexcept { return state_ == State::PANIC ? 0 : now_ - heard_; }

  /// AgentLogic Handler(a, m) with @p master the sender commands must come from: exactly one
  /// receive handler, in the spec's CASE order.
  Action Handler(const Message& m, std::uint16_t master) const noexcept {
    if (RecvMasterOk(m, master)) return Action::RecvMaster;
    if (RecvPongOk(m, master)) return Action::RecvPong;
    if (FromMaster(m, master) && Fresh(m)) {
      switch (m.type) {
        case MsgType::BEHAVIOUR: return Action::RecvBehaviour;
        case MsgType::START: return Action::RecvStart;
        case MsgType::STOP: return Action::RecvStop;
        case MsgType::PAUSE: return Action::RecvPause;
        case MsgType::RESUME: return Action::RecvResume;
        case MsgType::STANDBY: return Action::RecvStandby;
        case MsgType::CONTINUE: return Action::RecvContinue;
        case MsgType::RESTART: return Action::RecvRestart;
        default: break;
      }
    }
    if (RecvDuplicateOk(m, master)) return Action::RecvDuplicate;
    return Action::Ignore;
  }

  /// Spec Goto(a, s): enter @p s (the LED follows); emits state and LED events on change.
  void Goto(State s) noexcept {
    if (s != state_) {
      // Pre-votes are for standing from this PANIC: leaving it (a master found) forgets them, as
      // Election's HandleHeartbeat and AcceptRelay do.
      if (state_ == State::PANIC) el_.prevotes.clear();
      state_ = s;
      push_event(AgentEvent{AgentEvent::Kind::state, s, Led::DARK, ControlKind::stop});
      arm_lifecycle();
    }
    const Led l = led_of(s);
    if (l != led_) {
      led_ = l;
      push_event(AgentEvent{AgentEvent::Kind::led, s, l, ControlKind::stop});
    }
  }

  void control(ControlKind k) noexcept { push_event(AgentEvent{AgentEvent::Kind::control, state_, led_, k}); }
  /// Motors on: a fresh run (@p from_start) or the paused one continues.
  void motors_on(bool from_start, ControlKind start_kind = ControlKind::start) noexcept {
    if (from_start || !instance_) {
      control(start_kind);
    } else if (!motors_) {
      control(ControlKind::resume);
    }
    instance_ = true;
    motors_ = true;
  }
  /// Motors off, progress kept (a pause).
  void motors_pause() noexcept {
    if (motors_) control(ControlKind::pause);
    motors_ = false;
  }
  /// Spec Stopped(a): motors off, wait NONE; the run's progress is discarded.
  void Stopped() noexcept {
    if (instance_) control(ControlKind::stop);
    instance_ = false;
    motors_ = false;
    wait_ = Wait::NONE;
  }
  /// Spec RunFrom0(a): WORKING (@p to) from the first action, motors on.
  void RunFrom0(State to, ControlKind kind) noexcept {
    Goto(to);
    step_ = 0;
    wait_ = Wait::NONE;
    motors_on(true, kind);
  }
  void unload() noexcept {
    beh_.unload();
    step_ = 0;
  }

  /// Spec Answer(a, m, b, ans) after the handler changed the state: remember the answer, reset the
  /// silence, send it.
  void Answer(const Message& m, bool ack, Refusal reason = Refusal::wrong_state,
              const CheckReason* check = nullptr) noexcept {
    StoredAnswer a;
    a.src = id_;
    a.ref = m.msgid;
    a.ack = ack;
    a.reason = reason;
    if (check != nullptr) a.check = *check;
    win_.insert(m.sender, m.msgid, a);
    ++win_rev_;
    hear();
    send_answer(a);
  }
  void Refuse(const Message& m, Refusal r) noexcept { Answer(m, false, r); }
  /// NOT "missing device" for behaviour @p b (spec devOk), naming the device (name_missing_device).
  void RefuseMissing(const Message& m, const BehaviourSpec& b) noexcept {
    CheckReason why;
    if (!name_missing_device(cfg_.caps, plugged_, b, why)) return Refuse(m, Refusal::missing_device);
    Answer(m, false, Refusal::missing_device, &why);
  }

  void send_answer(const StoredAnswer& a) noexcept {
    char num[10];
    const std::string_view ref = decimal(a.ref, num);
    if (a.ack) {
      const std::string_view p[1] = {ref};
      emit_from(a.src, Dest::master, master_id(), MsgType::ACK, p, 1);
    } else {
      const std::string_view p[2] = {ref, a.reason_text()};
      emit_from(a.src, Dest::master, master_id(), MsgType::NOT, p, 2);
    }
  }

  // ------------------------------------------------------- receive handlers (AgentLogic)

  /// Spec RecvMasterOk: masterless agent (the table: IDLE, PANIC), fresh MASTER naming its id, to
  /// an assignable id.
  bool RecvMasterOk(const Message& m, std::uint16_t master) const noexcept {
    return FromMaster(m, master) && m.type == MsgType::MASTER && Fresh(m) && Allowed(Action::RecvMaster) &&
           ref_of(m) == id_ && is_assigned_id(m.receiver);
  }
  /// Spec RecvMaster: ACK from the new id, ACTIVE with the id from the receiver field, new session,
  /// following @p master of epoch @p e.
  void RecvMaster(const Message& m, Peer from, std::uint16_t master, std::uint32_t e) noexcept {
    Goto(next_state(state_, Action::RecvMaster).to);
    id_ = m.receiver;
    follow(master, e, 0, from);
    Stopped();
    unload();
    reset_clk();
    Answer(m, true);
  }

  /// Spec RecvPongOk: PONG from the master while synced (the table: ACTIVE, WORKING, PAUSED).
  bool RecvPongOk(const Message& m, std::uint16_t master) const noexcept {
    return FromMaster(m, master) && m.type == MsgType::PONG && Allowed(Action::RecvPong);
  }
  /// Spec RecvPong: the master is heard.
  void RecvPong(const Message&) noexcept { hear(); }

  /// Spec RecvBehaviour: ACK and load it if it can be run, else NOT with the reason. The robot's
  /// check (AgentConfig::check) runs on receipt, before the answer: a request it refuses gets NOT
  /// with its reason and changes nothing else (spec Refused, CheckReason).
  void RecvBehaviour(const Message& m) noexcept {
    const BehaviourSpec* b = find_behaviour(m.param(0));
    if (b == nullptr || !BehaviourStore::fits(m)) return Refuse(m, Refusal::unknown_behaviour);
    if (!dev_ok() || (b->devices & ~plugged_) != 0) return RefuseMissing(m, *b);
    {
      std::string_view params[kMaxArgs];
      const std::size_t n = m.param_count() - 1;
      for (std::size_t i = 0; i < n; ++i) params[i] = m.param(i + 1);
      CheckReason& why = refused_;
      why = CheckReason{};
      if (!cfg_.check(m.param(0), params, n, why)) {
        if (why.len == 0) why.set("refused by the robot's check");
        refused_now_ = true;  // the step's trace record carries the verdict
        return Answer(m, false, Refusal::unknown_behaviour, &why);
      }
    }
    if (state_ == State::PAUSED) Stopped();  // the paused run is replaced (wait, motors as spec)
    beh_.load(m);
    step_ = 0;
    wait_ = Wait::NONE;
    if (state_ == State::WORKING) motors_on(true);
    Answer(m, true);
  }

  /// Spec RecvStart: run the loaded behaviour from its start (ACTIVE, PAUSED, WORKING -> WORKING).
  void RecvStart(const Message& m, State to) noexcept {
    if (!beh_.loaded()) return Refuse(m, Refusal::no_behaviour);
    RunFrom0(to, ControlKind::start);
    Answer(m, true);
  }

  /// Spec RecvStop: WORKING / PAUSED -> ACTIVE, behaviour stopped and kept loaded.
  void RecvStop(const Message& m, State to) noexcept {
    Stopped();
    Goto(to);
    Answer(m, true);
  }

  /// Spec RecvPause: WORKING -> PAUSED, motors stopped, progress kept.
  void RecvPause(const Message& m, State to) noexcept {
    Goto(to);
    motors_pause();
    Answer(m, true);
  }

  /// Spec RecvResume: PAUSED -> WORKING where it was (still waiting if it was waiting).
  void RecvResume(const Message& m, State to) noexcept {
    Goto(to);
    if (wait_ == Wait::NONE) motors_on(false);
    Answer(m, true);
  }

  /// Spec RecvStandby: WORKING -> ACTIVE, behaviour stopped and kept loaded.
  void RecvStandby(const Message& m, State to) noexcept {
    Stopped();
    Goto(to);
    Answer(m, true);
  }

  /// Spec RecvContinue: after ACTION_INTERR (the table: WORKING waiting for CONTINUE), go on.
  void RecvContinue(const Message& m) noexcept {
    wait_ = Wait::NONE;
    motors_on(false);
    Answer(m, true);
  }

  /// Spec RecvRestart: after ACTION_ERR (the table: WORKING waiting for RESTART), the same
  /// behaviour again from its start.
  void RecvRestart(const Message& m, State to) noexcept {
    RunFrom0(to, ControlKind::restart);
    Answer(m, true);
  }

  /// Spec RecvDuplicateOk: a copy of an answered command or MASTER from the master.
  bool RecvDuplicateOk(const Message& m, std::uint16_t master) const noexcept {
    return FromMaster(m, master) && Answered(m) && Seen(m);
  }
  /// Spec RecvDuplicate: the stored answer again, nothing else.
  void RecvDuplicate(const Message& m) noexcept {
    const StoredAnswer* a = win_.find(m.sender, m.msgid);
    if (a != nullptr) send_answer(*a);
  }

  /// Spec Ignore: dropped silently.
  void Ignore(const Message&) noexcept {}

  // ---------------------------------------------------------------- time

  /// Spec Tick, repeated up to @p target (one record for the run of ticks): silence grows, the
  /// periodic message goes out when the heartbeat phase completes (at most once per run).
  void Tick(Millis target) noexcept {
    const AgentVars before = vars();
    const Millis ticks = target - now_;
    now_ = target;
    if (state_ == State::PANIC) hear();  // silence stays 0 in PANIC
    if (timers_.due(AgentTimer::periodic, now_)) {
      Periodic();
      timers_.set(AgentTimer::periodic, timers_.get(AgentTimer::periodic) + cfg_.timers[Timer::heartbeat]);
    }
    record(Action::Tick, before, {}, {}, ticks);
  }
  /// Spec Periodic(a): AGENT (IDLE), PANIC (PANIC; a candidate repeats its ELECT too) or PING(state).
  void Periodic() noexcept {
    if (el_.role == ElectionRole::master) return;  // the Master core run for it sends LEADER
    if (state_ == State::IDLE) {
      std::string_view p[kMaxParams];
      const std::size_t n = announcement(p);
      emit(Dest::broadcast, kBroadcastId, MsgType::AGENT, p, n);
    } else if (state_ == State::PANIC) {
      emit(Dest::broadcast, kBroadcastId, MsgType::PANIC, nullptr, 0);
      el_.RepeatElect(lifecycle(), *this);
    } else {
      const std::string_view p[1] = {to_string(wire_state(state_))};
      emit(Dest::master, master_id(), MsgType::PING, p, 1);
      reports_.retry();  // what the master has not acknowledged in a heartbeat goes again
      Send();
    }
  }

  /// AGENT's params into @p p, their count: the model, then the name of each device of the model
  /// in bit order ("left motor"; a bit without a name is left out), plugged or not: which are
  /// missing the master learns from EVENT DEVICE_DISCONNECTED (spec: AGENT's args are the model).
  std::size_t announcement(std::string_view (&p)[kMaxParams]) const noexcept {
    std::size_t n = 0;
    p[n++] = cfg_.caps.model;
    for (std::size_t bit = 0; bit < 32 && bit < cfg_.caps.device_name_count && n < kMaxParams; ++bit)
      if ((cfg_.caps.devices & (1u << bit)) != 0) p[n++] = cfg_.caps.device_names[bit];
    return n;
  }

  /// The timer that ends a silence in state @p s (AgentLogic SyncDue / LossDue), or none.
  static bool lifecycle_timer(State s, Timer& t) noexcept {
    switch (s) {
      case State::IDLE: t = Timer::sync; return true;
      case State::ACTIVE:
      case State::WORKING: t = Timer::loss; return true;
      case State::PAUSED: t = Timer::paused; return true;
      default: return false;
    }
  }
  /// Spec SyncTimeoutOk (SyncDue): IDLE (the table) silent for TSync.
  bool SyncTimeoutOk() const noexcept {
    return Allowed(Action::SyncTimeout) && silence() >= cfg_.timers[Timer::sync];
  }
  /// Spec SyncTimeout: IDLE without MASTER -> PANIC, PANIC broadcast.
  void SyncTimeout() noexcept { enter_panic(Action::SyncTimeout); }

  /// Spec HeartbeatLostOk (LossDue): ACTIVE / WORKING silent for TLoss, PAUSED for TPaused.
  bool HeartbeatLostOk() const noexcept {
    Timer t = Timer::loss;
    return Allowed(Action::HeartbeatLost) && lifecycle_timer(state_, t) && silence() >= cfg_.timers[t];
  }
  /// Spec HeartbeatLost: WORKING -> PAUSED (motors off, progress kept); ACTIVE, PAUSED -> PANIC
  /// (Election Timeout: nobody followed, the relay table dropped).
  void HeartbeatLost() noexcept {
    const State to = next_state(state_, Action::HeartbeatLost).to;
    if (to == State::PAUSED) {
      Goto(to);
      motors_pause();
    } else {
      enter_panic(Action::HeartbeatLost);
    }
  }

  // ------------------------------------------------ relay and election (Election.tla)

  /// What the election's guards and transitions need from the lifecycle.
  LifecycleView lifecycle() const noexcept {
    LifecycleView l;
    l.state = state_;
    l.id = id_;
    l.score = score();
    l.hears_master = el_.Following(state_) && now_ - heard_ < cfg_.timers[Timer::loss];
    const Millis vouch = cfg_.timers[Timer::vouch];
    l.vouches = el_.Following(state_) && (vouch == 0 || now_ - heard_ < vouch);
    l.now = now_;
    return l;
  }

  /// Spec RequestRelay's enabling condition: PANIC (or a candidate), the retry period is due.
  bool RequestRelayOk() const noexcept { return el_.RequestRelayOk(state_) && el_.relay_at <= now_; }
  /// Spec StartElection's enabling condition: Election's, and the back-off over.
  bool StartElectionOk() const noexcept {
    return el_.StartElectionOk(lifecycle()) && el_.StandDeadline(id_) <= now_;
  }
  /// Spec BecomeMaster's enabling condition: a candidate with votes of a strict majority.
  bool BecomeMasterOk() const noexcept { return el_.BecomeMasterOk(); }
  /// Spec BecomeMaster: AgentElection::BecomeMaster; a Master core runs for it from now on (node.hpp).
  void BecomeMaster() noexcept {
    el_.BecomeMaster(lifecycle(), *this);
    durable_changed();
  }

  /// Spec ApplyCommand: the inner datagram @p inner of master @p master in epoch @p e is handled as
  /// AgentLogic's Handler picked (@p h: RecvStart, a refusal, RecvDuplicate...); the answer goes to
  /// the master followed.
  void ApplyCommand(Action h, const Message& inner, Peer from, std::uint16_t master, std::uint32_t e) noexcept {
    Receive(h, inner, from, master, e);
  }

  void durable_changed() noexcept {
    const Durable d = el_.durable();
    if (d == durable_) return;
    durable_ = d;
    ++durable_rev_;
  }
  /// The master's id for answers and reports: the one followed, else the PC.
  std::uint16_t master_id() const noexcept { return el_.leader != 0 ? el_.leader : kMasterId; }

  // ------------------------------------------------------------ the timer table

  /// The master is heard now (silence 0): the lifecycle timeout starts again.
  void hear() noexcept {
    heard_ = now_;
    arm_lifecycle();
  }
  /// Lifecycle timer: heard + the timeout of the state (none in PANIC and OFF).
  void arm_lifecycle() noexcept {
    Timer t = Timer::sync;
    timers_.set(AgentTimer::lifecycle, lifecycle_timer(state_, t) ? heard_ + cfg_.timers[t] : kNever);
  }
  /// The earliest deadline: the TimerTable's or the election's (relay request, standing).
  Millis next_due() const noexcept {
    const Millis t = timers_.next(), e = el_.Deadline(id_);
    return e < t ? e : t;
  }
  Millis clk_origin() const noexcept {
    return timers_.get(AgentTimer::periodic) - cfg_.timers[Timer::heartbeat];
  }
  /// Spec `!.clk = 0`: the periodic phase restarts now.
  void reset_clk() noexcept { timers_.set(AgentTimer::periodic, now_ + cfg_.timers[Timer::heartbeat]); }

  /// Runs internal action @p f as spec action @p a with a trace record.
  template <typename F>
  void traced(Action a, F&& f) noexcept {
    const AgentVars before = vars();
    f();
    record(a, before, {}, {}, 0);
  }

  // ------------------------------------------------------ behaviour, devices

  /// Spec ActionOkOk: Running (the table: WORKING, wait NONE).
  bool ActionOkOk() const noexcept { return Allowed(Action::ActionOk); }
  /// Spec ActionOk: ACTION_OK(step), next action. The cycle length is the caller's business: the
  /// step counts up (spec: modulo Steps, the model's bound).
  void ActionOk() noexcept {
    char num[10];
    const std::string_view p[1] = {decimal(step_, num)};
    emit(Dest::master, master_id(), MsgType::ACTION_OK, p, 1);
    ++step_;
  }

  /// Spec ActionInterruptedOk: Running (the warning is one of Warnings by type).
  bool ActionInterruptedOk() const noexcept { return Allowed(Action::ActionInterrupted); }
  /// Spec ActionInterrupted: motors stop, ACTION_INTERR(step, event), wait for CONTINUE.
  void ActionInterrupted(Warning w) noexcept {
    wait_ = Wait::CONTINUE;
    motors_pause();
    char num[10];
    const std::string_view p[2] = {decimal(step_, num), to_string(w)};
    emit(Dest::master, master_id(), MsgType::ACTION_INTERR, p, 2);
  }

  /// Spec ActionFailedOk: Running.
  bool ActionFailedOk() const noexcept { return Allowed(Action::ActionFailed); }
  /// Spec ActionFailed: motors stop, ACTION_ERR(step, f), wait for RESTART.
  void ActionFailed(std::string_view f) noexcept {
    wait_ = Wait::RESTART;
    motors_pause();
    char num[10];
    const std::string_view p[2] = {decimal(step_, num), f};
    if (emit(Dest::master, master_id(), MsgType::ACTION_ERR, p, 2)) return;
    const std::string_view plain[2] = {p[0], "error"};  // f escaped (and relayed) does not fit
    emit(Dest::master, master_id(), MsgType::ACTION_ERR, plain, 2);
  }

  /// Spec SensorReportOk: Running.
  bool SensorReportOk() const noexcept { return Allowed(Action::SensorReport); }
  /// Spec SensorReport: SENSOR_VALUE(port, mode, value...).
  bool SensorReport(std::string_view port, std::string_view mode, const std::string_view* values,
                    std::size_t count) noexcept {
    std::string_view p[kMaxParams];
    p[0] = port;
    p[1] = mode;
    for (std::size_t i = 0; i < count; ++i) p[2 + i] = values[i];
    return emit(Dest::master, master_id(), MsgType::SENSOR_VALUE, p, count + 2);
  }

  /// Spec DeviceUnpluggedOk: alive (the table), all devices present, a port.
  bool DeviceUnpluggedOk(std::string_view port) const noexcept {
    return Allowed(Action::DeviceUnplugged) && dev_ok() && is_port_name(port);
  }
  /// Spec DeviceUnplugged: behaviour stopped and unloaded, WORKING / PAUSED -> ACTIVE,
  /// EVENT(DEVICE_DISCONNECTED, port) when synced.
  void DeviceUnplugged(std::string_view port) noexcept {
    const State was = state_;
    Stopped();
    unload();
    Goto(next_state(state_, Action::DeviceUnplugged).to);
    if (is_synced(was)) {
      const std::string_view p[2] = {"DEVICE_DISCONNECTED", port};
      emit(Dest::master, master_id(), MsgType::EVENT, p, 2);
    }
  }

  /// Spec DevicePluggedOk: alive (the table), a device missing, a port.
  bool DevicePluggedOk(std::string_view port) const noexcept {
    return Allowed(Action::DevicePlugged) && !dev_ok() && is_port_name(port);
  }
  /// Spec DevicePlugged: EVENT(DEVICE_CONNECTED, port) when synced.
  void DevicePlugged(std::string_view port) noexcept {
    if (is_synced(state_)) {
      const std::string_view p[2] = {"DEVICE_CONNECTED", port};
      emit(Dest::master, master_id(), MsgType::EVENT, p, 2);
    }
  }

  /// Spec RobotEventOk: Synced (the table: ACTIVE, WORKING, PAUSED), a port (the event is one of
  /// RobotEvents by type).
  bool RobotEventOk(std::string_view port) const noexcept {
    return Allowed(Action::RobotEvent) && is_port_name(port);
  }
  /// Spec RobotEvent: EVENT(event, port) to the master; nothing else changes.
  void RobotEvent(RobotEventKind e, std::string_view port) noexcept {
    const std::string_view p[2] = {to_string(e), port};
    emit(Dest::master, master_id(), MsgType::EVENT, p, 2);
  }

  /// Spec BatteryLowOk: alive (the table: every state but OFF).
  bool BatteryLowOk() const noexcept { return Allowed(Action::BatteryLow); }
  /// Spec BatteryLow: EVENT(BATTERY_LOW) when synced, stop, OFF.
  void BatteryLow() noexcept {
    if (is_synced(state_)) {
      const std::string_view p[1] = {"BATTERY_LOW"};
      emit(Dest::master, master_id(), MsgType::EVENT, p, 1);
    }
    Stopped();
    Goto(next_state(state_, Action::BatteryLow).to);
  }

  // ---------------------------------------------------------------- plumbing

  const BehaviourSpec* find_behaviour(std::string_view name) const noexcept {
    for (std::size_t i = 0; i < cfg_.caps.behaviour_count; ++i)
      if (cfg_.caps.behaviours[i].name == name) return &cfg_.caps.behaviours[i];
    return nullptr;
  }

  bool emit(Dest dest, std::uint16_t to, MsgType type, const std::string_view* params,
            std::size_t count) noexcept {
    if (dest == Dest::master && is_report(type)) return Make(to, type, params, count);
    return emit_from(id_, dest, to, type, params, count);
  }

  // ------------------------------------------------------ reliable reports (Reports.tla)

  /// Spec Make: the report is made as the datagram it would be (to @p to, with the next msgid),
  /// kept under the next number and, while the agent follows a master, sent to it at once in
  /// REPORT (with that msgid: its first sending); what the master has not acknowledged goes again
  /// through Send's window. False (nothing kept) when it does not fit: the datagram, or REPORT
  /// around it inside a RELAY, longer than TxBytes.
  bool Make(std::uint16_t to, MsgType type, const std::string_view* params, std::size_t count) noexcept {
    char buf[TxBytes];
    const EncodeResult r = encode_parts(id_, to, tx_.next_msgid(), static_cast<std::uint8_t>(type), params, count,
                                        buf, TxBytes);
    if (!r.ok() || !ReportTravels(std::string_view(buf, r.size))) return false;
    const std::uint32_t seq = reports_.Make(std::string_view(buf, r.size));
    if (seq == 0) return false;
    if (!CanSend()) return true;
    ReportTo();
    if (SendReport(seq, std::string_view(buf, r.size))) reports_.sent_at_once(seq);
    return true;
  }
  /// The master reports go to is master_id() in the epoch followed: when it is another one than
  /// before (a sync, an election, the PC back, the same agent elected again: a new Master core with
  /// a record of its own), that master has acknowledged nothing yet.
  void ReportTo() noexcept {
    if (master_id() == report_to_ && el_.following == report_epoch_) return;
    report_to_ = master_id();
    report_epoch_ = el_.following;
    reports_.new_master();
  }
  /// REPORT(@p seq, lo, @p d) to the master followed.
  bool SendReport(std::uint32_t seq, std::string_view d) noexcept {
    char a[10], b[10];
    const std::string_view p[3] = {decimal(seq, a), decimal(reports_.lo(), b), d};
    return emit_from(id_, Dest::master, master_id(), MsgType::REPORT, p, 3);
  }
  /// Reports go out while the agent follows a master that is not itself (an elected agent's own
  /// reports wait for the PC).
  bool CanSend() const noexcept { return is_synced(state_) && el_.role != ElectionRole::master; }
  /// REPORT(seq, first, @p d) with the largest numbers, relayed, fits a datagram of TxBytes.
  bool ReportTravels(std::string_view d) const noexcept {
    char rep[TxBytes], rel[TxBytes];
    const std::string_view p[3] = {"4294967295", "4294967295", d};
    const EncodeResult r = encode_parts(65535, 65535, 0xFFFFFFFFu, static_cast<std::uint8_t>(MsgType::REPORT), p, 3,
                                        rep, TxBytes);
    if (!r.ok()) return false;
    return encode_envelope(65535, 65535, 0xFFFFFFFFu, MsgType::RELAY, 65535, std::string_view(rep, r.size), rel,
                           TxBytes)
        .ok();
  }
  /// Spec Send: what the window allows of the held numbers goes to the master followed, the drop
  /// marker as REPORT_DROPPED(lo, mk), each report as REPORT(seq, lo, datagram). Nothing while the
  /// agent follows no master, or is the master itself (its own reports wait for the PC).
  void Send() noexcept {
    if (!CanSend()) return;
    ReportTo();
    bool marker = false;
    std::uint32_t seq = 0;
    std::string_view d;
    while (reports_.next(marker, seq, d)) {
      bool ok;
      if (marker) {
        char a[10], b[10];
        const std::string_view p[2] = {decimal(reports_.lo(), a), decimal(seq, b)};
        ok = emit_from(id_, Dest::master, master_id(), MsgType::REPORT_DROPPED, p, 2);
      } else {
        ok = SendReport(seq, d);
      }
      if (!ok) return;  // not reached: Make kept only what travels
      reports_.sent(seq);
    }
  }
  /// Spec TakeAck's enabling condition: REPORT_ACK to this agent's id from the PC or the master
  /// followed, of a number it made.
  Verdict TakeAckOk(const Message& m) const noexcept {
    if (m.receiver != id_) return Verdict{Action::Ignore, Ignored::misaddressed};
    if (m.sender != kMasterId && m.sender != master_id()) return Verdict{Action::Ignore, Ignored::foreign_sender};
    const auto n = m.param_u32(0);
    if (!n || *n > reports_.made()) return Verdict{Action::Ignore, Ignored::ignored_in_state};
    return Verdict{Action::TakeAck};
  }
  /// Spec TakeAck: the PC's acknowledgement frees what it covers; the master followed's stops its
  /// resending (an interim master's frees nothing: the PC's record is the mission's).
  void TakeAck(const Message& m) noexcept {
    reports_.TakeAck(*m.param_u32(0), m.sender == kMasterId, m.sender == master_id() && is_synced(state_));
  }
  /// A datagram to one peer (relay and election answers).
  bool emit_to(Peer peer, std::uint16_t to, MsgType type, const std::string_view* params,
               std::size_t count) noexcept {
    return emit_from(id_, Dest::peer, to, type, params, count, peer);
  }
  /// A new datagram from @p from (the agent, or the master core it runs) into the outbox; for the
  /// master, inside RELAY when relayed.
  bool emit_from(std::uint16_t from, Dest dest, std::uint16_t to, MsgType type,
                 const std::string_view* params, std::size_t count, Peer peer = 0) noexcept {
    return tx_.emit(from, dest, to, type, params, count, peer, el_.via);
  }
  /// Queues @p bytes unchanged (a relay forwarding an inner datagram): no msgid of ours.
  void emit_raw(Dest dest, Peer peer, std::string_view bytes) noexcept { tx_.emit_raw(dest, peer, bytes); }

  void push_event(const AgentEvent& e) noexcept { ev_.push_over(e, ev_overflowed_); }

  void record(Action a, const AgentVars& before, std::string_view msg, std::string_view event,
              Millis ticks, Action cmd = Action::Ignore, std::string_view port = {}) noexcept {
    if constexpr (Trace::enabled) {
      if (trace_ == nullptr) return;
      AgentTraceRecord r;
      r.action = a;
      r.msg = msg;
      r.event = event;
      r.port = port;
      if (refused_now_) r.check = refused_.view();
      r.ticks = ticks;
      r.now = now_;
      r.cmd = cmd;
      r.before = before;
      r.after = vars();
      trace_->record(r, *this);
    } else {
      (void)a, (void)before, (void)msg, (void)event, (void)ticks, (void)cmd, (void)port;
    }
  }

  AgentConfig cfg_;
  Trace* trace_ = nullptr;
  State state_ = State::IDLE;
  Led led_ = Led::YELLOW_BLINK;
  std::uint16_t id_;
  Millis now_;
  Millis heard_;  // spec silence = now_ - heard_ (0 in PANIC)
  std::uint32_t plugged_;
  TimerTable<AgentTimer, kAgentTableTimers> timers_;  // periodic: spec clk = (now - (periodic - heartbeat)) % heartbeat
  Peer master_peer_ = 0;
  bool motors_ = false;
  bool instance_ = false;  // the behaviour runner holds a run (started, maybe paused)
  Wait wait_ = Wait::NONE;
  std::uint32_t step_ = 0;
  BehaviourStore beh_;
  WindowType win_;
  std::uint32_t win_rev_ = 0;
  AgentOutbox<TxSlots, TxBytes> tx_;
  Ring<AgentEvent, EventSlots> ev_;
  std::uint32_t rejected_ = 0, ev_overflowed_ = 0;
  ElectionType el_;               // Election.tla's variables (fixed capacity, no heap)
  Durable durable_;               // durable() when durable_rev_ last changed
  std::uint32_t durable_rev_ = 0;
  CheckReason refused_;           // the robot's check refused the BEHAVIOUR of this step with this
  bool refused_now_ = false;      // ... (for its trace record; reset after it)
  Message rx_;                    // the datagram handle_datagram() decoded
  Message inner_;                 // the datagram inside a RELAY / EPOCH_CMD
  ReportsType reports_;           // Reports.tla: the reports not yet in the PC's record
  std::uint16_t report_to_ = 0;   // the master the report window counts for (ReportTo) ...
  std::uint32_t report_epoch_ = 0; // ... and the epoch it was followed in
};

}  // namespace ev3proto
