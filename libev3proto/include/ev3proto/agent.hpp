/// @file agent.hpp
/// @brief The agent (robot) protocol state machine of spec/tla/AgentLogic.tla, with no I/O.
///
/// Sans-I/O: the caller feeds received datagrams, the current monotonic time and device events in,
/// and drains datagrams to send, LED / state / behaviour-control events and the next deadline out.
/// No heap, no exceptions, no RTTI, no clocks, no globals, no randomness (the temporary id is drawn
/// by the caller). All memory is sized at compile time by the template parameters.
///
/// Every spec action has one handler of the same name (RecvMaster ... BatteryLow); handle_datagram()
/// dispatches like the spec's Handler(a, m): exactly one receive handler takes each message.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "core.hpp"
#include "dedupe.hpp"
#include "messages.hpp"
#include "timers.hpp"
#include "wire.hpp"

namespace ev3proto {

/// A behaviour the robot can run and the devices it needs (bit mask of the robot's device bits).
struct BehaviourSpec {
  std::string_view name;      ///< Name as the master sends it in BEHAVIOUR ("explore").
  std::uint32_t devices = 0;  ///< Device bits it needs (see Capabilities::devices).
};

/// What a robot can do, fixed at construction: its model, its behaviours, its devices.
struct Capabilities {
  std::string_view model;                   ///< Model announced in AGENT ("A").
  const BehaviourSpec* behaviours = nullptr; ///< Behaviours it implements.
  std::size_t behaviour_count = 0;          ///< Entries of @c behaviours.
  std::uint32_t devices = 0;                ///< Device bits of the model, all plugged at start.
};

/// Construction parameters of an Agent.
struct AgentConfig {
  Capabilities caps;             ///< Behaviours and devices (the table must outlive the agent).
  Timers timers;                 ///< Deadlines (timers.hpp); only sync, heartbeat, loss, paused used.
  std::uint16_t temp_id = 50000; ///< Temporary id drawn at random by the caller (50000..65535).
  std::uint32_t first_msgid = 1; ///< msgid of the first datagram the agent sends.
};

/// The answer recorded in the dedupe window for a command: sent again for a duplicate.
struct StoredAnswer {
  std::uint16_t src = 0;                      ///< Sender id the answer was sent with.
  std::uint32_t ref = 0;                      ///< The answered msgid.
  bool ack = true;                            ///< ACK (true) or NOT (false).
  Refusal reason = Refusal::wrong_state;      ///< NOT's reason.
};

/// A datagram the agent wants sent. @c bytes points into the agent and stays valid until the next
/// call that feeds the agent (handle_datagram, advance, an event).
struct Transmit {
  Dest dest = Dest::broadcast; ///< master or broadcast.
  Peer peer = 0;               ///< The master's peer handle for Dest::master (0 if unknown).
  std::string_view bytes;      ///< The encoded datagram (send it 3 times, as the transport does).
};

/// An event for the robot program: a state change, a LED pattern, or a behaviour control.
struct AgentEvent {
  /// Which field is meaningful.
  enum class Kind : std::uint8_t { state, led, control } kind = Kind::state;
  State state = State::IDLE;               ///< New state (Kind::state).
  Led led = Led::YELLOW_BLINK;             ///< New LED pattern (Kind::led).
  ControlKind control = ControlKind::stop; ///< What the behaviour runner must do (Kind::control);
                                           ///< start/restart run Agent::behaviour().
};

/// The loaded behaviour: name and key=value arguments as BEHAVIOUR carried them.
struct BehaviourView {
  std::string_view name;       ///< Behaviour name ("" when none is loaded: spec NoBehaviour).
  const char* data = nullptr;  ///< Argument bytes (internal).
  const std::uint16_t* ends = nullptr; ///< Argument end offsets (internal).
  std::size_t arg_count = 0;   ///< Number of arguments.
  /// Argument @p i ("speed=3"), or "" when out of range.
  std::string_view arg(std::size_t i) const noexcept {
    if (i >= arg_count) return {};
    const std::size_t b = i == 0 ? 0u : ends[i - 1];
    return std::string_view(data + b, ends[i] - b);
  }
};

/// The spec variables of one agent (AgentLogic `AgentType`) at one instant, for trace records.
struct AgentVars {
  State state = State::IDLE; ///< state
  Led led = Led::YELLOW_BLINK; ///< led
  std::uint16_t id = 0;      ///< id
  char beh[32] = {};         ///< beh ("NONE" is spelled as an empty name)
  std::uint8_t beh_len = 0;  ///< length of beh
  std::uint32_t step = 0;    ///< step
  Wait wait = Wait::NONE;    ///< wait
  bool motors = false;       ///< motors ("ON" / "OFF")
  bool dev_ok = true;        ///< devOk
  Millis silence = 0;        ///< silence (ms = ticks)
  Millis clk = 0;            ///< clk (ms since the periodic phase origin, modulo heartbeat)
  std::uint32_t win_rev = 0; ///< changes whenever win changes (the window itself: Agent::window())
  /// The behaviour name.
  std::string_view beh_name() const noexcept { return std::string_view(beh, beh_len); }
};

/// One trace record: a spec action the agent took, its arguments, and the variables around it.
struct AgentTraceRecord {
  Action action = Action::Tick; ///< The spec action (handler) taken.
  std::string_view msg;         ///< Receive handlers: the datagram as received.
  std::string_view event;       ///< ActionInterrupted: the warning name.
  Millis ticks = 0;             ///< Tick: number of consecutive spec Ticks this record stands for.
  Millis now = 0;               ///< Time after the action.
  AgentVars before;             ///< Variables before.
  AgentVars after;              ///< Variables after.
};

/// The agent core.
/// @tparam Trace trace sink: NoTrace (default, compiles to nothing) or a type with
///         `static constexpr bool enabled = true` and `template <class A> void record(const
///         AgentTraceRecord&, const A& agent)` (see trace.hpp).
/// @tparam Window dedupe window entries (spec Window; protocol default 50).
/// @tparam TxSlots datagrams that can wait in the output queue (the oldest is dropped when full).
/// @tparam TxBytes largest datagram the agent can send.
/// @tparam EventSlots events that can wait in the event queue (the oldest is dropped when full).
/// @tparam ArgBytes bytes for the loaded behaviour's arguments.
template <typename Trace = NoTrace, std::size_t Window = 50, std::size_t TxSlots = 8,
          std::size_t TxBytes = 512, std::size_t EventSlots = 16, std::size_t ArgBytes = 512>
class Agent {
 public:
  /// Longest behaviour name the agent stores.
  static constexpr std::size_t kMaxNameLen = sizeof(AgentVars::beh);
  /// Most behaviour arguments (BEHAVIOUR has at most 31 besides the name).
  static constexpr std::size_t kMaxArgs = kMaxParams - 1;
  /// "No deadline".
  static constexpr Millis kNever = ~Millis{0};
  /// The dedupe window type (payload: the recorded answer).
  using WindowType = DedupeWindow<Window, StoredAnswer>;

  /// A fresh agent in IDLE at time @p now (spec Init with id = temp id).
  Agent(const AgentConfig& config, Millis now, Trace* trace = nullptr) noexcept
      : cfg_(config), trace_(trace), id_(config.temp_id), msgid_(config.first_msgid), now_(now),
        heard_(now), periodic_at_(now + config.timers[Timer::heartbeat]),
        plugged_(config.caps.devices) {}

  // ---------------------------------------------------------------- inputs

  /// Time moves to @p now: spec Ticks (periodic AGENT / PING / PANIC) and, before time moves past
  /// them, due timeouts (SyncTimeout, HeartbeatLost). A @p now in the past changes nothing.
  void advance(Millis now) noexcept {
    if (state_ == State::OFF) {
      if (now > now_) now_ = now;
      return;
    }
    for (;;) {
      if (SyncTimeoutOk()) {
        SyncTimeout();
        continue;
      }
      if (HeartbeatLostOk()) {
        HeartbeatLost();
        continue;
      }
      const Millis due = periodic_at_ < timeout_at() ? periodic_at_ : timeout_at();
      const Millis target = due < now ? due : now;
      if (target <= now_) break;
      Tick(target);
    }
  }

  /// Same as advance(): the name quinn-style callers expect.
  void handle_timeout(Millis now) noexcept { advance(now); }

  /// A datagram @p bytes arrived from @p from at @p now. Time advances first; a datagram that does
  /// not decode is dropped (counted in rejected(), not a spec step); otherwise exactly one receive
  /// handler takes it (spec Handler). Returns the action taken (Ignore when dropped).
  Action handle_datagram(std::string_view bytes, Peer from, Millis now) noexcept {
    advance(now);
    if (!decode(bytes, rx_).ok()) {
      ++rejected_;
      return Action::Ignore;
    }
    if (state_ == State::OFF) return Action::Ignore;  // OFF takes no step at all (Agent.tla)
    const Action h = Handler(rx_);
    const AgentVars before = vars();
    switch (h) {
      case Action::RecvMaster: RecvMaster(rx_, from); break;
      case Action::RecvPong: RecvPong(rx_); break;
      case Action::RecvBehaviour: RecvBehaviour(rx_); break;
      case Action::RecvStart: RecvStart(rx_); break;
      case Action::RecvStop: RecvStop(rx_); break;
      case Action::RecvPause: RecvPause(rx_); break;
      case Action::RecvResume: RecvResume(rx_); break;
      case Action::RecvStandby: RecvStandby(rx_); break;
      case Action::RecvContinue: RecvContinue(rx_); break;
      case Action::RecvRestart: RecvRestart(rx_); break;
      case Action::RecvDuplicate: RecvDuplicate(rx_); break;
      default: Ignore(rx_); break;
    }
    record(h, before, bytes, {}, 0);
    return h;
  }

  /// The running action finished (spec ActionOk). Returns false (nothing done) unless Running.
  bool action_ok(Millis now) noexcept {
    advance(now);
    if (!ActionOkOk()) return false;
    const AgentVars before = vars();
    ActionOk();
    record(Action::ActionOk, before, {}, {}, 0);
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

  /// The running action failed (spec ActionFailed). Returns false unless Running.
  bool action_failed(Millis now) noexcept {
    advance(now);
    if (!ActionFailedOk()) return false;
    const AgentVars before = vars();
    ActionFailed();
    record(Action::ActionFailed, before, {}, {}, 0);
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

  /// Device bit(s) @p device were unplugged. The first unplug while all devices are present is the
  /// spec's DeviceUnplugged; further unplugs only update the mask. Returns true if the spec action
  /// was taken.
  bool device_unplugged(std::uint32_t device, Millis now) noexcept {
    advance(now);
    if (!DeviceUnpluggedOk()) {
      plugged_ &= ~device;
      return false;
    }
    const AgentVars before = vars();
    plugged_ &= ~device;
    if (dev_ok()) return false;  // not a device of the model
    DeviceUnplugged();
    record(Action::DeviceUnplugged, before, {}, {}, 0);
    return true;
  }

  /// Device bit(s) @p device are back. When that makes every device of the model present again it
  /// is the spec's DevicePlugged. Returns true if the spec action was taken.
  bool device_plugged(std::uint32_t device, Millis now) noexcept {
    advance(now);
    const bool ok = DevicePluggedOk();
    const AgentVars before = vars();
    plugged_ |= device & cfg_.caps.devices;
    if (!ok || !dev_ok()) return false;  // still a device missing (or OFF)
    DevicePlugged();
    record(Action::DevicePlugged, before, {}, {}, 0);
    return true;
  }

  /// The battery is low (spec BatteryLow): tell the master, stop, shut down (OFF).
  bool battery_low(Millis now) noexcept {
    advance(now);
    if (!BatteryLowOk()) return false;
    const AgentVars before = vars();
    BatteryLow();
    record(Action::BatteryLow, before, {}, {}, 0);
    return true;
  }

  // ---------------------------------------------------------------- outputs

  /// Takes the oldest datagram to send; false when there is none.
  bool poll_transmit(Transmit& out) noexcept {
    if (tx_count_ == 0) return false;
    TxSlot& s = tx_[tx_head_];
    out.dest = s.dest;
    out.peer = s.dest == Dest::master ? master_peer_ : 0;
    out.bytes = std::string_view(s.bytes, s.size);
    tx_head_ = (tx_head_ + 1) % TxSlots;
    --tx_count_;
    return true;
  }

  /// Takes the oldest event (state, LED, behaviour control); false when there is none.
  bool poll_event(AgentEvent& out) noexcept {
    if (ev_count_ == 0) return false;
    out = ev_[ev_head_];
    ev_head_ = (ev_head_ + 1) % EventSlots;
    --ev_count_;
    return true;
  }

  /// When the caller must call advance() next at the latest (kNever in OFF).
  Millis next_deadline() const noexcept {
    if (state_ == State::OFF) return kNever;
    const Millis t = timeout_at();
    return periodic_at_ < t ? periodic_at_ : t;
  }

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
    return BehaviourView{std::string_view(beh_name_, beh_len_), args_, arg_ends_, arg_count_};
  }
  /// The agent's time (the latest now it was given).
  Millis now() const noexcept { return now_; }
  /// Time the master was last heard (a fresh command, MASTER or PONG).
  Millis last_heard() const noexcept { return heard_; }
  /// The dedupe window (read-only).
  const WindowType& window() const noexcept { return win_; }
  /// Datagrams that did not decode.
  std::uint32_t rejected() const noexcept { return rejected_; }
  /// msgid the next datagram will carry (for a program's last message of its own at exit).
  std::uint32_t next_msgid() const noexcept { return msgid_; }
  /// Datagrams or events dropped because the caller did not drain the queues.
  std::uint32_t overflowed() const noexcept { return overflowed_; }
  /// The spec variables now.
  AgentVars vars() const noexcept {
    AgentVars v;
    v.state = state_;
    v.led = led_;
    v.id = id_;
    std::memcpy(v.beh, beh_name_, beh_len_);
    v.beh_len = static_cast<std::uint8_t>(beh_len_);
    v.step = step_;
    v.wait = wait_;
    v.motors = motors_;
    v.dev_ok = dev_ok();
    v.silence = state_ == State::PANIC ? 0 : now_ - heard_;
    v.clk = (now_ - clk_origin()) % cfg_.timers[Timer::heartbeat];
    v.win_rev = win_rev_;
    return v;
  }

  /// The receive handler the spec's Handler(a, m) picks for @p m (at most one applies).
  Action Handler(const Message& m) const noexcept {
    if (RecvMasterOk(m)) return Action::RecvMaster;
    if (RecvPongOk(m)) return Action::RecvPong;
    if (FromMaster(m) && Fresh(m)) {
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
    if (RecvDuplicateOk(m)) return Action::RecvDuplicate;
    return Action::Ignore;
  }

 private:
  struct TxSlot {
    Dest dest = Dest::broadcast;
    std::size_t size = 0;
    char bytes[TxBytes];
  };

  // ------------------------------------------------------------ spec helpers

  /// AgentLogic AddressedTo: to its id, to everyone, or a MASTER naming its id while masterless.
  bool AddressedTo(const Message& m) const noexcept {
    if (m.receiver == id_ || m.receiver == kBroadcastId) return true;
    return is_masterless(state_) && m.type == MsgType::MASTER && ref_of(m) == id_ &&
           is_assigned_id(m.receiver);
  }
  /// AgentLogic FromMaster.
  bool FromMaster(const Message& m) const noexcept {
    return state_ != State::OFF && m.sender == kMasterId && AddressedTo(m);
  }
  /// AgentLogic Fresh: (src, msgid) not in the window.
  bool Fresh(const Message& m) const noexcept { return !win_.contains(m.sender, m.msgid); }
  /// AgentLogic Answered: types answered with ACK / NOT.
  static bool Answered(const Message& m) noexcept {
    return m.type == MsgType::MASTER ||
           (m.type >= MsgType::BEHAVIOUR && m.type <= MsgType::RESTART);
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
      case MsgType::ACTION_ERR: {
        const auto v = m.param_u32(0);
        return v ? *v : 0u;
      }
      default: return 0;
    }
  }
  bool Running() const noexcept { return state_ == State::WORKING && wait_ == Wait::NONE; }

  Millis timeout_at() const noexcept {
    switch (state_) {
      case State::IDLE: return heard_ + cfg_.timers[Timer::sync];
      case State::ACTIVE:
      case State::WORKING: return heard_ + cfg_.timers[Timer::loss];
      case State::PAUSED: return heard_ + cfg_.timers[Timer::paused];
      default: return kNever;
    }
  }
  Millis clk_origin() const noexcept { return periodic_at_ - cfg_.timers[Timer::heartbeat]; }
  /// Spec `!.clk = 0`: the periodic phase restarts now.
  void reset_clk() noexcept { periodic_at_ = now_ + cfg_.timers[Timer::heartbeat]; }

  /// Spec Goto(a, s): enter @p s (the LED follows); emits state and LED events on change.
  void Goto(State s) noexcept {
    if (s != state_) {
      state_ = s;
      push_event(AgentEvent{AgentEvent::Kind::state, s, Led::DARK, ControlKind::stop});
    }
    const Led l = led_of(s);
    if (l != led_) {
      led_ = l;
      push_event(AgentEvent{AgentEvent::Kind::led, s, l, ControlKind::stop});
    }
  }
  /// Enter the state the transition table gives for @p by from the current state.
  void GotoBy(Action by) noexcept { Goto(next_state(state_, by)); }

  void control(ControlKind k) noexcept {
    push_event(AgentEvent{AgentEvent::Kind::control, state_, led_, k});
  }
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
  /// Spec RunFrom0(a): WORKING from the first action, motors on.
  void RunFrom0(Action by, ControlKind kind) noexcept {
    GotoBy(by);
    step_ = 0;
    wait_ = Wait::NONE;
    motors_on(true, kind);
  }
  void unload() noexcept {
    beh_len_ = 0;
    arg_count_ = 0;
    step_ = 0;
  }

  /// Spec Answer(a, m, b, ans) after the handler changed the state: remember the answer, reset the
  /// silence, send it.
  void Answer(const Message& m, bool ack, Refusal reason = Refusal::wrong_state) noexcept {
    StoredAnswer a;
    a.src = id_;
    a.ref = m.msgid;
    a.ack = ack;
    a.reason = reason;
    win_.insert(m.sender, m.msgid, a);
    ++win_rev_;
    heard_ = now_;
    send_answer(a);
  }
  void Refuse(const Message& m, Refusal r) noexcept { Answer(m, false, r); }

  void send_answer(const StoredAnswer& a) noexcept {
    char num[10];
    const std::string_view ref = number(a.ref, num);
    if (a.ack) {
      const std::string_view p[1] = {ref};
      emit_from(a.src, Dest::master, kMasterId, MsgType::ACK, p, 1);
    } else {
      const std::string_view p[2] = {ref, to_string(a.reason)};
      emit_from(a.src, Dest::master, kMasterId, MsgType::NOT, p, 2);
    }
  }

  // ------------------------------------------------------- receive handlers

  /// Spec RecvMasterOk: masterless agent, fresh MASTER naming its id, to an assignable id.
  bool RecvMasterOk(const Message& m) const noexcept {
    return FromMaster(m) && m.type == MsgType::MASTER && Fresh(m) && is_masterless(state_) &&
           ref_of(m) == id_ && is_assigned_id(m.receiver);
  }
  /// Spec RecvMaster: ACK from the new id, ACTIVE with the id from the receiver field, new session.
  void RecvMaster(const Message& m, Peer from) noexcept {
    GotoBy(Action::RecvMaster);
    id_ = m.receiver;
    master_peer_ = from;
    Stopped();
    unload();
    reset_clk();
    Answer(m, true);
  }

  /// Spec RecvPongOk: PONG from the master while synced.
  bool RecvPongOk(const Message& m) const noexcept {
    return FromMaster(m) && m.type == MsgType::PONG && is_synced(state_);
  }
  /// Spec RecvPong: the master is heard.
  void RecvPong(const Message&) noexcept { heard_ = now_; }

  /// Spec RecvBehaviour: ACK and load it if it can be run, else NOT with the reason.
  void RecvBehaviour(const Message& m) noexcept {
    if (!is_synced(state_)) return Refuse(m, Refusal::wrong_state);
    const BehaviourSpec* b = find_behaviour(m.param(0));
    if (b == nullptr || !fits(m)) return Refuse(m, Refusal::unknown_behaviour);
    if (!dev_ok() || (b->devices & ~plugged_) != 0) return Refuse(m, Refusal::missing_device);
    if (state_ == State::PAUSED) Stopped();  // the paused run is replaced (wait, motors as spec)
    load(m);
    step_ = 0;
    wait_ = Wait::NONE;
    if (state_ == State::WORKING) motors_on(true);
    Answer(m, true);
  }

  /// Spec RecvStart: run the loaded behaviour from its start (ACTIVE, PAUSED, WORKING).
  void RecvStart(const Message& m) noexcept {
    if (!is_synced(state_)) return Refuse(m, Refusal::wrong_state);
    if (beh_len_ == 0) return Refuse(m, Refusal::no_behaviour);
    RunFrom0(Action::RecvStart, ControlKind::start);
    Answer(m, true);
  }

  /// Spec RecvStop: WORKING / PAUSED -> ACTIVE, behaviour stopped and kept loaded.
  void RecvStop(const Message& m) noexcept {
    if (state_ != State::WORKING && state_ != State::PAUSED) return Refuse(m, Refusal::wrong_state);
    Stopped();
    GotoBy(Action::RecvStop);
    Answer(m, true);
  }

  /// Spec RecvPause: WORKING -> PAUSED, motors stopped, progress kept.
  void RecvPause(const Message& m) noexcept {
    if (state_ != State::WORKING) return Refuse(m, Refusal::wrong_state);
    GotoBy(Action::RecvPause);
    motors_pause();
    Answer(m, true);
  }

  /// Spec RecvResume: PAUSED -> WORKING where it was (still waiting if it was waiting).
  void RecvResume(const Message& m) noexcept {
    if (state_ != State::PAUSED) return Refuse(m, Refusal::wrong_state);
    GotoBy(Action::RecvResume);
    if (wait_ == Wait::NONE) motors_on(false);
    Answer(m, true);
  }

  /// Spec RecvStandby: WORKING -> ACTIVE, behaviour stopped and kept loaded.
  void RecvStandby(const Message& m) noexcept {
    if (state_ != State::WORKING) return Refuse(m, Refusal::wrong_state);
    Stopped();
    GotoBy(Action::RecvStandby);
    Answer(m, true);
  }

  /// Spec RecvContinue: after ACTION_INTERR, go on with the behaviour.
  void RecvContinue(const Message& m) noexcept {
    if (state_ != State::WORKING || wait_ != Wait::CONTINUE) return Refuse(m, Refusal::wrong_state);
    wait_ = Wait::NONE;
    motors_on(false);
    Answer(m, true);
  }

  /// Spec RecvRestart: after ACTION_ERR, the same behaviour again from its start.
  void RecvRestart(const Message& m) noexcept {
    if (state_ != State::WORKING || wait_ != Wait::RESTART) return Refuse(m, Refusal::wrong_state);
    RunFrom0(Action::RecvRestart, ControlKind::restart);
    Answer(m, true);
  }

  /// Spec RecvDuplicateOk: a copy of an answered command or MASTER from the master.
  bool RecvDuplicateOk(const Message& m) const noexcept {
    return FromMaster(m) && Answered(m) && !Fresh(m);
  }
  /// Spec RecvDuplicate: the stored answer again, nothing else.
  void RecvDuplicate(const Message& m) noexcept {
    const StoredAnswer* a = win_.find(m.sender, m.msgid);
    if (a != nullptr) send_answer(*a);
  }

  /// Spec Ignore: dropped silently.
  void Ignore(const Message&) noexcept {}

  // ---------------------------------------------------------------- time

  /// Spec TickOk: alive and no timeout due.
  bool TickOk() const noexcept { return state_ != State::OFF && !SyncTimeoutOk() && !HeartbeatLostOk(); }
  /// Spec Tick, repeated up to @p target (one record for the run of ticks): silence grows, the
  /// periodic message goes out when the heartbeat phase completes (at most once per run).
  void Tick(Millis target) noexcept {
    const AgentVars before = vars();
    const Millis ticks = target - now_;
    now_ = target;
    if (state_ == State::PANIC) heard_ = now_;  // silence stays 0 in PANIC
    if (now_ == periodic_at_) {
      Periodic();
      periodic_at_ += cfg_.timers[Timer::heartbeat];
    }
    record(Action::Tick, before, {}, {}, ticks);
  }
  /// Spec Periodic(a): AGENT (IDLE), PANIC (PANIC) or PING(state).
  void Periodic() noexcept {
    if (state_ == State::IDLE) {
      const std::string_view p[1] = {cfg_.caps.model};
      emit(Dest::broadcast, kBroadcastId, MsgType::AGENT, p, 1);
    } else if (state_ == State::PANIC) {
      emit(Dest::broadcast, kBroadcastId, MsgType::PANIC, nullptr, 0);
    } else {
      const std::string_view p[1] = {to_string(wire_state(state_))};
      emit(Dest::master, kMasterId, MsgType::PING, p, 1);
    }
  }

  /// Spec SyncTimeoutOk (SyncDue).
  bool SyncTimeoutOk() const noexcept {
    return state_ == State::IDLE && now_ - heard_ >= cfg_.timers[Timer::sync];
  }
  /// Spec SyncTimeout: IDLE without MASTER -> PANIC, PANIC broadcast.
  void SyncTimeout() noexcept {
    const AgentVars before = vars();
    GotoBy(Action::SyncTimeout);
    heard_ = now_;
    reset_clk();
    emit(Dest::broadcast, kBroadcastId, MsgType::PANIC, nullptr, 0);
    record(Action::SyncTimeout, before, {}, {}, 0);
  }

  /// Spec HeartbeatLostOk (LossDue).
  bool HeartbeatLostOk() const noexcept {
    switch (state_) {
      case State::ACTIVE:
      case State::WORKING: return now_ - heard_ >= cfg_.timers[Timer::loss];
      case State::PAUSED: return now_ - heard_ >= cfg_.timers[Timer::paused];
      default: return false;
    }
  }
  /// Spec HeartbeatLost: WORKING -> PAUSED (motors off, progress kept); ACTIVE, PAUSED -> PANIC.
  void HeartbeatLost() noexcept {
    const AgentVars before = vars();
    if (state_ == State::WORKING) {
      GotoBy(Action::HeartbeatLost);
      motors_pause();
    } else {
      Stopped();
      GotoBy(Action::HeartbeatLost);
      heard_ = now_;
      reset_clk();
      emit(Dest::broadcast, kBroadcastId, MsgType::PANIC, nullptr, 0);
    }
    record(Action::HeartbeatLost, before, {}, {}, 0);
  }

  // ------------------------------------------------------ behaviour, devices

  /// Spec ActionOkOk: Running.
  bool ActionOkOk() const noexcept { return Running(); }
  /// Spec ActionOk: ACTION_OK(step), next action. The cycle length is the caller's business: the
  /// step counts up (spec: modulo Steps, the model's bound).
  void ActionOk() noexcept {
    char num[10];
    const std::string_view p[1] = {number(step_, num)};
    emit(Dest::master, kMasterId, MsgType::ACTION_OK, p, 1);
    ++step_;
  }

  /// Spec ActionInterruptedOk: Running (the warning is one of Warnings by type).
  bool ActionInterruptedOk() const noexcept { return Running(); }
  /// Spec ActionInterrupted: motors stop, ACTION_INTERR(step, event), wait for CONTINUE.
  void ActionInterrupted(Warning w) noexcept {
    wait_ = Wait::CONTINUE;
    motors_pause();
    char num[10];
    const std::string_view p[2] = {number(step_, num), to_string(w)};
    emit(Dest::master, kMasterId, MsgType::ACTION_INTERR, p, 2);
  }

  /// Spec ActionFailedOk: Running.
  bool ActionFailedOk() const noexcept { return Running(); }
  /// Spec ActionFailed: motors stop, ACTION_ERR(step, "error"), wait for RESTART.
  void ActionFailed() noexcept {
    wait_ = Wait::RESTART;
    motors_pause();
    char num[10];
    const std::string_view p[2] = {number(step_, num), "error"};
    emit(Dest::master, kMasterId, MsgType::ACTION_ERR, p, 2);
  }

  /// Spec SensorReportOk: Running.
  bool SensorReportOk() const noexcept { return Running(); }
  /// Spec SensorReport: SENSOR_VALUE(port, mode, value...).
  bool SensorReport(std::string_view port, std::string_view mode, const std::string_view* values,
                    std::size_t count) noexcept {
    std::string_view p[kMaxParams];
    p[0] = port;
    p[1] = mode;
    for (std::size_t i = 0; i < count; ++i) p[2 + i] = values[i];
    return emit(Dest::master, kMasterId, MsgType::SENSOR_VALUE, p, count + 2);
  }

  /// Spec DeviceUnpluggedOk: alive and all devices present.
  bool DeviceUnpluggedOk() const noexcept { return state_ != State::OFF && dev_ok(); }
  /// Spec DeviceUnplugged: behaviour stopped and unloaded, WORKING / PAUSED -> ACTIVE, EVENT.
  void DeviceUnplugged() noexcept {
    const State was = state_;
    Stopped();
    unload();
    GotoBy(Action::DeviceUnplugged);
    if (is_synced(was)) {
      const std::string_view p[1] = {"DEVICE_DISCONNECTED"};
      emit(Dest::master, kMasterId, MsgType::EVENT, p, 1);
    }
  }

  /// Spec DevicePluggedOk: alive and a device missing.
  bool DevicePluggedOk() const noexcept { return state_ != State::OFF && !dev_ok(); }
  /// Spec DevicePlugged: EVENT(DEVICE_CONNECTED) when synced.
  void DevicePlugged() noexcept {
    if (is_synced(state_)) {
      const std::string_view p[1] = {"DEVICE_CONNECTED"};
      emit(Dest::master, kMasterId, MsgType::EVENT, p, 1);
    }
  }

  /// Spec BatteryLowOk: alive.
  bool BatteryLowOk() const noexcept { return state_ != State::OFF; }
  /// Spec BatteryLow: EVENT(BATTERY_LOW) when synced, stop, OFF.
  void BatteryLow() noexcept {
    if (is_synced(state_)) {
      const std::string_view p[1] = {"BATTERY_LOW"};
      emit(Dest::master, kMasterId, MsgType::EVENT, p, 1);
    }
    Stopped();
    GotoBy(Action::BatteryLow);
  }

  // ---------------------------------------------------------------- plumbing

  const BehaviourSpec* find_behaviour(std::string_view name) const noexcept {
    for (std::size_t i = 0; i < cfg_.caps.behaviour_count; ++i)
      if (cfg_.caps.behaviours[i].name == name) return &cfg_.caps.behaviours[i];
    return nullptr;
  }
  /// True when BEHAVIOUR's name and arguments fit the fixed storage.
  bool fits(const Message& m) const noexcept {
    if (m.param(0).size() > kMaxNameLen || m.param(0).empty()) return false;
    std::size_t bytes = 0;
    for (std::size_t i = 1; i < m.param_count(); ++i) bytes += m.param(i).size();
    return bytes <= ArgBytes;
  }
  void load(const Message& m) noexcept {
    const std::string_view n = m.param(0);
    std::memcpy(beh_name_, n.data(), n.size());
    beh_len_ = n.size();
    std::size_t used = 0;
    arg_count_ = 0;
    for (std::size_t i = 1; i < m.param_count(); ++i) {
      const std::string_view a = m.param(i);
      if (!a.empty()) std::memcpy(args_ + used, a.data(), a.size());
      used += a.size();
      arg_ends_[arg_count_++] = static_cast<std::uint16_t>(used);
    }
  }

  static std::string_view number(std::uint32_t v, char (&buf)[10]) noexcept {
    char* e = detail::write_decimal(buf, v);
    return std::string_view(buf, static_cast<std::size_t>(e - buf));
  }

  bool emit(Dest dest, std::uint16_t to, MsgType type, const std::string_view* params,
            std::size_t count) noexcept {
    return emit_from(id_, dest, to, type, params, count);
  }
  /// Encodes a new datagram (next msgid) into the output queue; the oldest is dropped when full.
  bool emit_from(std::uint16_t from, Dest dest, std::uint16_t to, MsgType type,
                 const std::string_view* params, std::size_t count) noexcept {
    // When full, the slot written is the oldest one; encode_parts() writes nothing on refusal.
    TxSlot& s = tx_[(tx_head_ + tx_count_) % TxSlots];
    const EncodeResult r = encode_parts(from, to, msgid_, static_cast<std::uint8_t>(type), params,
                                        count, s.bytes, TxBytes);
    if (!r.ok()) return false;
    if (tx_count_ == TxSlots) {
      tx_head_ = (tx_head_ + 1) % TxSlots;
      --tx_count_;
      ++overflowed_;
    }
    ++msgid_;
    s.dest = dest;
    s.size = r.size;
    ++tx_count_;
    return true;
  }

  void push_event(const AgentEvent& e) noexcept {
    if (ev_count_ == EventSlots) {
      ev_head_ = (ev_head_ + 1) % EventSlots;
      --ev_count_;
      ++overflowed_;
    }
    ev_[(ev_head_ + ev_count_) % EventSlots] = e;
    ++ev_count_;
  }

  void record(Action a, const AgentVars& before, std::string_view msg, std::string_view event,
              Millis ticks) noexcept {
    if constexpr (Trace::enabled) {
      if (trace_ == nullptr) return;
      AgentTraceRecord r;
      r.action = a;
      r.msg = msg;
      r.event = event;
      r.ticks = ticks;
      r.now = now_;
      r.before = before;
      r.after = vars();
      trace_->record(r, *this);
    } else {
      (void)a, (void)before, (void)msg, (void)event, (void)ticks;
    }
  }

  AgentConfig cfg_;
  Trace* trace_ = nullptr;
  State state_ = State::IDLE;
  Led led_ = Led::YELLOW_BLINK;
  std::uint16_t id_;
  std::uint32_t msgid_;
  Millis now_;
  Millis heard_;        // spec silence = now_ - heard_ (0 in PANIC)
  Millis periodic_at_;  // next periodic send; spec clk = (now_ - (periodic_at_ - heartbeat)) % heartbeat
  std::uint32_t plugged_;
  Peer master_peer_ = 0;
  bool motors_ = false;
  bool instance_ = false;  // the behaviour runner holds a run (started, maybe paused)
  Wait wait_ = Wait::NONE;
  std::uint32_t step_ = 0;
  char beh_name_[kMaxNameLen] = {};
  std::size_t beh_len_ = 0;
  char args_[ArgBytes] = {};
  std::uint16_t arg_ends_[kMaxArgs] = {};
  std::size_t arg_count_ = 0;
  WindowType win_;
  std::uint32_t win_rev_ = 0;
  TxSlot tx_[TxSlots];
  std::size_t tx_head_ = 0, tx_count_ = 0;
  AgentEvent ev_[EventSlots];
  std::size_t ev_head_ = 0, ev_count_ = 0;
  std::uint32_t rejected_ = 0, overflowed_ = 0;
  Message rx_;
};

}  // namespace ev3proto
