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

/// "Compute the score from the capabilities" (ElectionConfig::score).
inline constexpr std::uint32_t kAutoScore = ~std::uint32_t{0};

/// Relay and election (spec/tla/Election.tla). Off by default: the agent is then exactly the
/// AgentLogic.tla agent (one master, epoch 1). epoch and voted_for are Election's persistent
/// variables: pass back what durable() said last (SD card) after a restart.
struct ElectionConfig {
  bool enabled = false;           ///< Relay and election on.
  std::uint32_t epoch = 1;        ///< Highest epoch seen (persisted).
  std::uint16_t voted_for = 0;    ///< Vote in that epoch, 0 = none (persisted).
  std::uint32_t score = kAutoScore; ///< Election Score (lower = weaker, stands first, wins).
};

/// What the firmware must keep on stable storage (Election's epoch and votedFor): write it before
/// sending the datagrams polled after the call that changed it (AgentEvent::Kind::durable).
struct Durable {
  std::uint32_t epoch = 1;     ///< Highest epoch seen.
  std::uint16_t voted_for = 0; ///< Whom the agent voted for in that epoch (0 = nobody).
};

/// Construction parameters of an Agent.
struct AgentConfig {
  Capabilities caps;             ///< Behaviours and devices (the table must outlive the agent).
  Timers timers;                 ///< Deadlines (timers.hpp); the agent uses sync, heartbeat, loss,
                                 ///< paused, relay_retry, backoff, backoff_step, candidate.
  std::uint16_t temp_id = 50000; ///< Temporary id drawn at random by the caller (50000..65535).
  std::uint32_t first_msgid = 1; ///< msgid of the first datagram the agent sends.
  ElectionConfig election;       ///< Relay and election (off by default).
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
  Dest dest = Dest::broadcast; ///< master, broadcast, or peer (relay and election answers).
  Peer peer = 0;               ///< Dest::master: the master's peer handle (the relay's when
                               ///< relayed; 0 if unknown); Dest::peer: the receiver's handle.
  std::string_view bytes;      ///< The encoded datagram (send it 3 times, as the transport does).
};

/// An event for the robot program: a state change, a LED pattern, or a behaviour control.
struct AgentEvent {
  /// Which field is meaningful.
  /// (Election outputs are observers, not events: Agent::role(), Agent::durable(); docs/core.md.)
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
  // Election.tla variables (traced only when the election is enabled).
  bool election = false;     ///< Election enabled (trace the variables below).
  Role role = Role::none;    ///< With state: Election life (CANDIDATE, MASTER are PANIC + role).
  std::uint32_t epoch = 1;   ///< epoch
  std::uint16_t voted_for = 0; ///< votedFor (0 = NoNode)
  std::uint16_t leader = 0;  ///< leader (0 = NoNode)
  std::uint32_t following = 0; ///< following
  std::uint16_t via = 0;     ///< via (0 = NoNode)
  std::uint32_t relay_rev = 0; ///< changes whenever relays / offered / votes change
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
  Action cmd = Action::Ignore;  ///< ApplyCommand: the receive handler that took the inner datagram.
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
/// @tparam RelaySlots agents one relay serves at once (and pending offers); Election relays.
template <typename Trace = NoTrace, std::size_t Window = 50, std::size_t TxSlots = 8,
          std::size_t TxBytes = 512, std::size_t EventSlots = 16, std::size_t ArgBytes = 512,
          std::size_t RelaySlots = 4>
class Agent {
 public:
  /// Fleet members an agent keeps (LEADER carries at most 30).
  static constexpr std::size_t kMaxMembers = kMaxParams - 2;
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
        plugged_(config.caps.devices), epoch_(config.election.epoch == 0 ? 1 : config.election.epoch),
        voted_for_(config.election.voted_for) {}

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
      if (RequestRelayOk()) {
        traced(Action::RequestRelay, [this] { RequestRelay(); });
        continue;
      }
      if (StartElectionOk()) {
        traced(Action::StartElection, [this] { StartElection(); });
        continue;
      }
      if (BecomeMasterOk()) {
        traced(Action::BecomeMaster, [this] { BecomeMaster(); });
        continue;
      }
      Millis due = periodic_at_ < timeout_at() ? periodic_at_ : timeout_at();
      if (election_due() < due) due = election_due();
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
    const AgentVars before = vars();
    cmd_ = Action::Ignore;
    const Action h = Dispatch(rx_, from);
    record(h, before, bytes, {}, 0);
    if (BecomeMasterOk()) traced(Action::BecomeMaster, [this] { BecomeMaster(); });
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
    out.peer = s.dest == Dest::master ? master_peer_ : s.dest == Dest::peer ? s.peer : 0;
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
    Millis t = timeout_at();
    if (election_due() < t) t = election_due();
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

  // ------------------------------------------------------ election observers

  /// Election role (CANDIDATE / MASTER of Election.tla; the state is then PANIC).
  Role role() const noexcept { return role_; }
  /// Highest epoch seen (Election epoch).
  std::uint32_t epoch() const noexcept { return epoch_; }
  /// What to keep on stable storage (epoch, votedFor): write it when durable_rev() changed, before
  /// sending what the call that changed it queued (a VOTE must not outlive a lost votedFor).
  Durable durable() const noexcept { return Durable{epoch_, voted_for_}; }
  /// Changes whenever durable() changes.
  std::uint32_t durable_rev() const noexcept { return durable_rev_; }
  /// The epoch this agent last became master of (0 = never): with role() == master, the program
  /// runs a Master core seeded with it and members() (docs/core.md, "An agent becomes master").
  std::uint32_t master_epoch() const noexcept { return master_epoch_; }
  /// The master followed (Election leader; 0 = none). Before any election: 1 (the PC) when synced.
  std::uint16_t leader() const noexcept { return leader_; }
  /// The epoch of that master (Election following; 0 = none).
  std::uint32_t following() const noexcept { return following_; }
  /// The relay's id when relayed (Election via; 0 = direct).
  std::uint16_t via() const noexcept { return via_; }
  /// Agents this agent relays for (Election relays).
  std::size_t relay_count() const noexcept { return relay_count_; }
  /// The i-th relayed agent's id.
  std::uint16_t relayed(std::size_t i) const noexcept { return i < relay_count_ ? relays_[i].id : 0; }
  /// Agents offered a relay since the master last changed (Election offered).
  std::size_t offered_count() const noexcept { return offered_count_; }
  /// The i-th offered agent's id.
  std::uint16_t offered(std::size_t i) const noexcept { return i < offered_count_ ? offered_[i].id : 0; }
  /// Votes counted as a candidate / master (Election votes).
  std::size_t vote_count() const noexcept { return vote_count_; }
  /// The i-th vote.
  std::uint16_t vote(std::size_t i) const noexcept { return i < vote_count_ ? votes_[i] : 0; }
  /// PREVOTE_OKs counted for standing in the next epoch (Election prevotes; those of an older
  /// epoch no longer count).
  std::size_t prevote_count() const noexcept { return prevote_epoch_ == epoch_ ? prevote_count_ : 0; }
  /// The i-th pre-vote's sender.
  std::uint16_t prevote(std::size_t i) const noexcept { return i < prevote_count() ? prevotes_[i] : 0; }
  /// The fleet membership last published by the followed master (LEADER), quorums count against it.
  std::size_t member_count() const noexcept { return member_count_; }
  /// The i-th member id.
  std::uint16_t member(std::size_t i) const noexcept { return i < member_count_ ? members_[i] : 0; }
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
    std::memcpy(v.beh, beh_name_, beh_len_);
    v.beh_len = static_cast<std::uint8_t>(beh_len_);
    v.step = step_;
    v.wait = wait_;
    v.motors = motors_;
    v.dev_ok = dev_ok();
    v.silence = state_ == State::PANIC ? 0 : now_ - heard_;
    v.clk = (now_ - clk_origin()) % cfg_.timers[Timer::heartbeat];
    v.win_rev = win_rev_;
    v.election = cfg_.election.enabled;
    v.role = role_;
    v.epoch = epoch_;
    v.voted_for = voted_for_;
    v.leader = leader_;
    v.following = following_;
    v.via = via_;
    v.relay_rev = relay_rev_;
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
    Peer peer = 0;
    std::size_t size = 0;
    char bytes[TxBytes];
  };
  struct PeerEntry {
    std::uint16_t id = 0;
    Peer peer = 0;
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
    return state_ != State::OFF && m.sender == cur_master_ && AddressedTo(m);
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
      // Pre-votes are for standing from this PANIC: leaving it (a master found) forgets them, as
      // Election's HandleHeartbeat and AcceptRelay do.
      if (state_ == State::PANIC) clear_prevotes();
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
      emit_from(a.src, Dest::master, master_id(), MsgType::ACK, p, 1);
    } else {
      const std::string_view p[2] = {ref, to_string(a.reason)};
      emit_from(a.src, Dest::master, master_id(), MsgType::NOT, p, 2);
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
    adopt_epoch(cmd_epoch_);
    leader_ = cur_master_;
    following_ = cmd_epoch_;
    via_ = 0;
    relay_at_ = stand_at_ = kNever;
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
    if (role_ == Role::master) return;  // the Master core run for it sends LEADER
    if (state_ == State::IDLE) {
      const std::string_view p[1] = {cfg_.caps.model};
      emit(Dest::broadcast, kBroadcastId, MsgType::AGENT, p, 1);
    } else if (state_ == State::PANIC) {
      emit(Dest::broadcast, kBroadcastId, MsgType::PANIC, nullptr, 0);
    } else {
      const std::string_view p[1] = {to_string(wire_state(state_))};
      emit(Dest::master, master_id(), MsgType::PING, p, 1);
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
      Unfollow();  // Election Timeout: leader, following, via cleared; relays dropped
      enter_panic();
    }
    record(Action::HeartbeatLost, before, {}, {}, 0);
  }

  // ------------------------------------------------ relay and election (Election.tla)

  /// Routes a decoded datagram to its spec handler: relay / election types to Election's, an
  /// EPOCH_CMD through the fence to ApplyCommand, everything else to AgentLogic's Handler().
  Action Dispatch(const Message& m, Peer from) noexcept {
    cur_master_ = leader_ != 0 ? leader_ : kMasterId;
    cmd_epoch_ = 1;
    if (m.type >= MsgType::RELAY_REQ && m.type <= MsgType::PREVOTE_OK) {
      const Action e = cfg_.election.enabled && m.sender != id_ ? ElectionHandler(m) : Action::Ignore;
      switch (e) {
        case Action::OfferRelay: OfferRelay(m, from); break;
        case Action::GrantPreVote: GrantPreVote(m, from); break;
        case Action::HandlePreVote: HandlePreVote(m); break;
        case Action::AcceptRelay: AcceptRelay(m, from); break;
        case Action::HandleAccept: HandleAccept(m, from); break;
        case Action::Forward: Forward(m); break;
        case Action::RelayDropped: RelayDropped(m); break;
        case Action::HandleElect: HandleElect(m, from); break;
        case Action::HandleVote: HandleVote(m); break;
        case Action::HandleHeartbeat: HandleHeartbeat(m, from); break;
        case Action::HandleStale:
          if (m.type == MsgType::EPOCH_CMD) {
            Stale(m.sender, from);
            return Action::Ignore;
          }
          HandleStale(m);
          break;
        case Action::ApplyCommand: ApplyCommand(m, from); break;
        default: Ignore(m); break;
      }
      return e;
    }
    if (cfg_.election.enabled && epoch_ > 1 && Answered(m) && AddressedTo(m)) {
      // A bare command counts as epoch 1, older than ours: fenced, the sender learns our epoch.
      Stale(m.sender, from);
      return Action::Ignore;
    }
    const Action h = Handler(m);
    Run(h, m, from);
    return h;
  }

  /// The AgentLogic receive handler @p h on @p m.
  void Run(Action h, const Message& m, Peer from) noexcept {
    switch (h) {
      case Action::RecvMaster: RecvMaster(m, from); break;
      case Action::RecvPong: RecvPong(m); break;
      case Action::RecvBehaviour: RecvBehaviour(m); break;
      case Action::RecvStart: RecvStart(m); break;
      case Action::RecvStop: RecvStop(m); break;
      case Action::RecvPause: RecvPause(m); break;
      case Action::RecvResume: RecvResume(m); break;
      case Action::RecvStandby: RecvStandby(m); break;
      case Action::RecvContinue: RecvContinue(m); break;
      case Action::RecvRestart: RecvRestart(m); break;
      case Action::RecvDuplicate: RecvDuplicate(m); break;
      default: Ignore(m); break;
    }
  }

  /// Which Election handler takes relay / election datagram @p m (Ignore when none is enabled).
  Action ElectionHandler(const Message& m) noexcept {
    switch (m.type) {
      case MsgType::RELAY_REQ:
        if (OfferRelayOk(m)) return Action::OfferRelay;
        return GrantPreVoteOk(m) ? Action::GrantPreVote : Action::Ignore;
      case MsgType::PREVOTE_OK: return HandlePreVoteOk(m) ? Action::HandlePreVote : Action::Ignore;
      case MsgType::RELAY_OFFER: return AcceptRelayOk(m) ? Action::AcceptRelay : Action::Ignore;
      case MsgType::RELAY_ACCEPT: return HandleAcceptOk(m) ? Action::HandleAccept : Action::Ignore;
      case MsgType::RELAY: return ForwardOk(m) ? Action::Forward : Action::Ignore;
      case MsgType::RELAY_DROP: return RelayDroppedOk(m) ? Action::RelayDropped : Action::Ignore;
      case MsgType::ELECT: return HandleElectOk(m) ? Action::HandleElect : Action::Ignore;
      case MsgType::VOTE: return HandleVoteOk(m) ? Action::HandleVote : Action::Ignore;
      case MsgType::LEADER: return HandleHeartbeatOk(m) ? Action::HandleHeartbeat : Action::Ignore;
      case MsgType::EPOCH_STALE: return HandleStaleOk(m) ? Action::HandleStale : Action::Ignore;
      case MsgType::EPOCH_CMD:
        if (!ApplyCommandOk(m)) return Action::Ignore;
        // An older epoch: no spec step (ApplyCommand is not enabled); answered EPOCH_STALE.
        return *m.param_u32(0) < epoch_ ? Action::HandleStale : Action::ApplyCommand;
      default: return Action::Ignore;  // RELAY_ROUTE, HANDOVER: the master's
    }
  }

  bool ToMe(const Message& m) const noexcept { return m.receiver == id_ && is_assigned_id(id_); }
  bool Following() const noexcept { return is_synced(state_) && leader_ != 0; }
  /// Election HeartbeatOK, as the agent sees it: it follows a master heard within the loss timeout.
  bool HeartbeatOK() const noexcept {
    return Following() && now_ - heard_ < cfg_.timers[Timer::loss];
  }
  /// Election: p follows a master in its current epoch over a direct link (may offer / relay).
  bool DirectFollower() const noexcept { return Following() && following_ == epoch_ && via_ == 0; }

  /// Spec RequestRelay's enabling condition: PANIC (or a candidate), the retry period is due.
  bool RequestRelayOk() const noexcept {
    return cfg_.election.enabled && state_ == State::PANIC && role_ != Role::master && relay_at_ <= now_;
  }
  /// Spec RequestRelay: RELAY_REQ(epoch, score) broadcast, again after relay_retry. It is also the
  /// pre-vote request: peers without a master answer PREVOTE_OK.
  void RequestRelay() noexcept {
    relay_at_ = now_ + cfg_.timers[Timer::relay_retry];
    char num[10], sc[10];
    const std::string_view p[2] = {number(epoch_, num), number(score(), sc)};
    emit(Dest::broadcast, kBroadcastId, MsgType::RELAY_REQ, p, 2);
  }

  /// Spec GrantPreVote's enabling condition: no master here (PANIC or candidate), the asker's epoch
  /// not older than ours and its score (RELAY_REQ's second param) not higher than ours.
  bool GrantPreVoteOk(const Message& m) const noexcept {
    const auto e = m.param_u32(0);
    const auto sc = m.param_u32(1);
    return m.receiver == kBroadcastId && is_assigned_id(m.sender) && is_assigned_id(id_) &&
           state_ == State::PANIC && role_ != Role::master && e && sc && *e >= epoch_ && *sc <= score();
  }
  /// Spec GrantPreVote: PREVOTE_OK(epoch of the request) to the asker; nothing else changes.
  void GrantPreVote(const Message& m, Peer from) noexcept {
    const std::string_view p[1] = {m.param(0)};
    emit_to(from, m.sender, MsgType::PREVOTE_OK, p, 1);
  }

  /// Spec HandlePreVote's enabling condition: still without a master, for our current epoch, from a
  /// member not counted yet.
  bool HandlePreVoteOk(const Message& m) const noexcept {
    const auto e = m.param_u32(0);
    if (!ToMe(m) || state_ != State::PANIC || role_ == Role::master || !e || *e != epoch_) return false;
    for (std::size_t i = 0; i < prevote_count(); ++i)
      if (prevotes_[i] == m.sender) return false;
    return is_member(m.sender);
  }
  /// Spec HandlePreVote: one more pre-vote for standing in the next epoch.
  void HandlePreVote(const Message& m) noexcept {
    if (prevote_epoch_ != epoch_) {
      prevote_epoch_ = epoch_;
      prevote_count_ = 0;
    }
    if (prevote_count_ < kMaxMembers) prevotes_[prevote_count_++] = m.sender;
    ++relay_rev_;
  }
  void clear_prevotes() noexcept {
    if (prevote_count_ != 0) ++relay_rev_;
    prevote_count_ = 0;
  }

  /// Spec OfferRelay's enabling condition (one hop: only a direct follower offers). An agent already
  /// in the relay table is offered to again: it asks only after losing its relay state.
  bool OfferRelayOk(const Message& m) const noexcept {
    const auto e = m.param_u32(0);
    return m.receiver == kBroadcastId && is_assigned_id(m.sender) && DirectFollower() && e &&
           *e <= epoch_;
  }
  /// Spec OfferRelay: RELAY_OFFER(epoch, master) to the requester, remembered in offered.
  void OfferRelay(const Message& m, Peer from) noexcept {
    add(offered_, offered_count_, m.sender, from);
    char num[10], who[10];
    const std::string_view p[2] = {number(epoch_, num), number(leader_, who)};
    emit_to(from, m.sender, MsgType::RELAY_OFFER, p, 2);
  }

  /// Spec AcceptRelay's enabling condition: PANIC (not standing), the offer's epoch not older.
  bool AcceptRelayOk(const Message& m) const noexcept {
    const auto e = m.param_u32(0);
    const auto x = m.param_u16(1);
    return ToMe(m) && state_ == State::PANIC && role_ == Role::none && e && x && *x != 0 &&
           *x != id_ && *e >= epoch_ && is_assigned_id(m.sender);
  }
  /// Spec AcceptRelay: follow the relay's master in its epoch through it (ACTIVE), RELAY_ACCEPT.
  void AcceptRelay(const Message& m, Peer from) noexcept {
    const std::uint32_t e = *m.param_u32(0);
    GotoBy(Action::AcceptRelay);
    adopt_epoch(e);
    leader_ = *m.param_u16(1);
    following_ = e;
    via_ = m.sender;
    master_peer_ = from;
    heard_ = now_;
    reset_clk();
    relay_at_ = stand_at_ = kNever;
    clear_prevotes();
    const std::string_view p[2] = {m.param(0), m.param(1)};
    emit_to(from, m.sender, MsgType::RELAY_ACCEPT, p, 2);
  }

  /// Spec HandleAccept's enabling condition: answers an offer made since the master last changed,
  /// and the relay still follows that master in that epoch directly.
  bool HandleAcceptOk(const Message& m) const noexcept {
    const auto e = m.param_u32(0);
    const auto x = m.param_u16(1);
    return ToMe(m) && Following() && via_ == 0 && e && x && *e == following_ && *x == leader_ &&
           find(offered_, offered_count_, m.sender) != nullptr && relay_count_ < RelaySlots;
  }
  /// Spec HandleAccept: the agent enters the relay table; RELAY_ROUTE(epoch, agent) to the master.
  void HandleAccept(const Message& m, Peer from) noexcept {
    remove(offered_, offered_count_, m.sender);
    add(relays_, relay_count_, m.sender, from);
    char num[10], who[10];
    const std::string_view p[2] = {number(epoch_, num), number(m.sender, who)};
    emit(Dest::master, leader_, MsgType::RELAY_ROUTE, p, 2);
  }

  /// Spec Forward's enabling condition: a direct follower relaying for the target (master -> agent)
  /// or for the sender (agent -> master); the inner datagram decodes and is not itself a RELAY.
  bool ForwardOk(const Message& m) noexcept {
    const auto target = m.param_u16(0);
    if (!ToMe(m) || !Following() || via_ != 0 || !target) return false;
    if (!decode(m.param(1), inner_).ok() || inner_.type == MsgType::RELAY) return false;
    if (m.sender == leader_) return find(relays_, relay_count_, *target) != nullptr;
    return *target == leader_ && find(relays_, relay_count_, m.sender) != nullptr &&
           inner_.sender == m.sender;
  }
  /// Spec Forward: the inner datagram goes on unchanged (sender, msgid: dedupe end to end).
  void Forward(const Message& m) noexcept {
    if (m.sender == leader_) {
      emit_raw(Dest::peer, find(relays_, relay_count_, *m.param_u16(0))->peer, m.param(1));
    } else {
      emit_raw(Dest::master, 0, m.param(1));
    }
  }

  /// Spec RelayDropped's enabling condition: from our relay while following through it.
  bool RelayDroppedOk(const Message& m) const noexcept {
    return ToMe(m) && via_ != 0 && m.sender == via_ && is_synced(state_);
  }
  /// Spec RelayDropped: back to PANIC (behaviour stopped), then relay requests / standing.
  void RelayDropped(const Message&) noexcept {
    Stopped();
    GotoBy(Action::RelayDropped);
    Unfollow();
    heard_ = now_;
    reset_clk();
    emit(Dest::broadcast, kBroadcastId, MsgType::PANIC, nullptr, 0);
    enter_panic();
  }

  /// Spec StartElection's enabling condition: PANIC (or a candidate whose timeout passed), an
  /// assigned id, a known membership, the back-off over, and pre-votes of a majority of the
  /// membership (itself included).
  bool StartElectionOk() const noexcept {
    return cfg_.election.enabled && state_ == State::PANIC && role_ != Role::master &&
           stand_at_ <= now_ && member_count_ > 0 && is_assigned_id(id_) && epoch_ < 0xFFFFFFFFu &&
           prevote_quorum();
  }
  /// The pre-votes of the current epoch and our own make a strict majority of the membership.
  bool prevote_quorum() const noexcept {
    return 2 * (prevote_count() + (is_member(id_) ? 1u : 0u)) > member_count_;
  }
  /// Spec StartElection: epoch + 1, vote for itself, ELECT(epoch, score, records) broadcast.
  void StartElection() noexcept {
    ++epoch_;
    voted_for_ = id_;
    durable_changed();
    vote_count_ = 0;
    if (is_member(id_)) votes_[vote_count_++] = id_;
    ++relay_rev_;
    records_ = 0;
    set_role(Role::candidate);
    clear_prevotes();
    // If this candidacy stalls, ask again (pre-votes for the next epoch) before standing again.
    relay_at_ = now_ + cfg_.timers[Timer::candidate];
    stand_at_ = now_ + cfg_.timers[Timer::candidate] + backoff();
    char e[10], sc[10], rc[10];
    const std::string_view p[3] = {number(epoch_, e), number(score(), sc), number(records_, rc)};
    emit(Dest::broadcast, kBroadcastId, MsgType::ELECT, p, 3);
  }

  /// Spec HandleElect's enabling condition (the CASE arms that change something).
  bool HandleElectOk(const Message& m) const noexcept {
    const auto e = m.param_u32(0);
    const auto sc = m.param_u32(1);
    if (m.receiver != kBroadcastId || !e || !sc || state_ == State::IDLE || !is_assigned_id(id_))
      return false;
    if (*e < epoch_) return true;                                    // EPOCH_STALE
    if (HeartbeatOK() && m.sender != kMasterId) return false;        // a healthy follower
    const bool newer = *e > epoch_;
    const bool grant = (newer || voted_for_ == 0 || voted_for_ == m.sender) && *sc <= score();
    return newer || grant;
  }
  /// Spec HandleElect: adopt a newer epoch (stepping down), grant the one vote of the epoch to a
  /// candidate not stronger than us (VOTE), or tell an older candidate our epoch (EPOCH_STALE).
  void HandleElect(const Message& m, Peer from) noexcept {
    const std::uint32_t e = *m.param_u32(0);
    if (e < epoch_) return Stale(m.sender, from);
    const bool newer = e > epoch_;
    const bool grant = (newer || voted_for_ == 0 || voted_for_ == m.sender) && *m.param_u32(1) <= score();
    if (newer) {
      StepDown(Action::HandleElect);
      epoch_ = e;
      clear_prevotes();
      voted_for_ = 0;
      records_ = 0;
    }
    ++records_;
    if (grant) {
      voted_for_ = m.sender;
      // Give the candidate time to win before standing ourselves.
      if (state_ == State::PANIC && role_ == Role::none)
        stand_at_ = now_ + cfg_.timers[Timer::candidate] + backoff();
    }
    durable_changed();
    if (grant) {
      char num[10], who[10];
      const std::string_view p[2] = {number(e, num), number(m.sender, who)};
      emit_to(from, m.sender, MsgType::VOTE, p, 2);
    }
  }

  /// Spec HandleVote's enabling condition: a candidate's vote of its epoch, not counted yet.
  bool HandleVoteOk(const Message& m) const noexcept {
    const auto e = m.param_u32(0);
    const auto c = m.param_u16(1);
    if (!ToMe(m) || role_ != Role::candidate || !e || !c || *e != epoch_ || *c != id_) return false;
    for (std::size_t i = 0; i < vote_count_; ++i)
      if (votes_[i] == m.sender) return false;
    return is_member(m.sender);
  }
  /// Spec HandleVote: one more vote.
  void HandleVote(const Message& m) noexcept {
    votes_[vote_count_++] = m.sender;
    ++relay_rev_;
  }

  /// Spec BecomeMaster's enabling condition: a candidate with votes of a strict majority.
  bool BecomeMasterOk() const noexcept {
    return role_ == Role::candidate && member_count_ > 0 && 2 * vote_count_ > member_count_;
  }
  /// Spec BecomeMaster: master of its epoch; first LEADER(epoch, id, members) broadcast; the
  /// program starts a Master core (AgentEvent role master).
  void BecomeMaster() noexcept {
    stand_at_ = kNever;
    set_role(Role::master);
    char e[10], me[10], ids[kMaxMembers][10];
    std::string_view p[kMaxParams];
    p[0] = number(epoch_, e);
    p[1] = number(id_, me);
    for (std::size_t i = 0; i < member_count_; ++i) p[2 + i] = number(members_[i], ids[i]);
    emit(Dest::broadcast, kBroadcastId, MsgType::LEADER, p, 2 + member_count_);
  }

  /// Spec HandleHeartbeat's enabling condition: a master's LEADER (not an IDLE agent's business).
  bool HandleHeartbeatOk(const Message& m) const noexcept {
    const auto e = m.param_u32(0);
    const auto s = m.param_u16(1);
    if (m.receiver != kBroadcastId || !e || !s || *s != m.sender || state_ == State::IDLE ||
        !is_assigned_id(id_))
      return false;
    if (*e < epoch_) return true;  // EPOCH_STALE
    return role_ != Role::master || *e > epoch_;
  }
  /// Spec HandleHeartbeat: an older master is told our epoch; otherwise follow this one directly
  /// (PANIC / candidate / master -> ACTIVE; WORKING whose master changed -> PAUSED), learn the
  /// membership, and drop the relay table when the master changed.
  void HandleHeartbeat(const Message& m, Peer from) noexcept {
    const std::uint32_t e = *m.param_u32(0);
    if (e < epoch_) return Stale(m.sender, from);
    const bool change = leader_ != m.sender || following_ != e;
    if (change) {
      DropRelays();
      if (state_ == State::WORKING) {
        GotoBy(Action::HandleHeartbeat);
        motors_pause();
      }
    }
    if (state_ == State::PANIC) {
      GotoBy(Action::HandleHeartbeat);
      reset_clk();
    }
    set_role(Role::none);
    adopt_epoch(e);
    leader_ = m.sender;
    following_ = e;
    via_ = 0;
    master_peer_ = from;
    heard_ = now_;
    relay_at_ = stand_at_ = kNever;
    clear_prevotes();
    member_count_ = 0;
    for (std::size_t i = 2; i < m.param_count() && member_count_ < kMaxMembers; ++i) {
      const auto id = m.param_u16(i);
      if (id && is_assigned_id(*id)) members_[member_count_++] = *id;
    }
  }

  /// Spec HandleStale's enabling condition: a newer epoch than ours.
  bool HandleStaleOk(const Message& m) const noexcept {
    const auto e = m.param_u32(0);
    return ToMe(m) && e && *e > epoch_;
  }
  /// Spec HandleStale: adopt the epoch, step down (master / candidate -> PANIC, WORKING ->
  /// PAUSED), stop following an older master, drop the relay table.
  void HandleStale(const Message& m) noexcept {
    StepDown(Action::HandleStale);
    epoch_ = *m.param_u32(0);
    clear_prevotes();
    voted_for_ = 0;
    durable_changed();
  }

  /// Spec ApplyCommand's enabling condition, checked on the outer EPOCH_CMD: the inner datagram
  /// decodes and is the sender's; the epoch is not older than ours (older ones: EPOCH_STALE).
  bool ApplyCommandOk(const Message& m) noexcept {
    const auto e = m.param_u32(0);
    if (!e || !decode(m.param(1), inner_).ok() || inner_.sender != m.sender ||
        inner_.type == MsgType::EPOCH_CMD || inner_.type == MsgType::RELAY)
      return false;
    if (*e < epoch_) return true;  // answered EPOCH_STALE
    cur_master_ = m.sender;
    cmd_epoch_ = *e;
    // The master of epoch e syncs a masterless agent (MASTER inside EPOCH_CMD).
    if (inner_.type == MsgType::MASTER) return RecvMasterOk(inner_) || RecvDuplicateOk(inner_);
    return leader_ == m.sender && following_ == *e && *e == epoch_;  // the fence
  }
  /// Spec ApplyCommand: the inner datagram is handled as AgentLogic's Handler picks (RecvStart,
  /// a refusal, RecvDuplicate...), the answer goes to the master we follow.
  void ApplyCommand(const Message&, Peer from) noexcept {
    cmd_ = Handler(inner_);
    Run(cmd_, inner_, from);
  }

  // ------------------------------------------------------------ election plumbing

  /// EPOCH_STALE(epoch) to @p to at @p peer.
  void Stale(std::uint16_t to, Peer peer) noexcept {
    char num[10];
    const std::string_view p[1] = {number(epoch_, num)};
    emit_to(peer, to, MsgType::EPOCH_STALE, p, 1);
  }
  /// Election SteppedDown and the clearing that goes with a newer epoch.
  void StepDown(Action by) noexcept {
    if (state_ == State::WORKING) {
      GotoBy(by);
      motors_pause();
    }
    if (role_ != Role::none) {
      set_role(Role::none);
      enter_panic();
    }
    Unfollow();
  }
  /// leader, following, via cleared; relays dropped (RELAY_DROP), offers forgotten.
  void Unfollow() noexcept {
    leader_ = 0;
    following_ = 0;
    via_ = 0;
    DropRelays();
  }
  void DropRelays() noexcept {
    for (std::size_t i = 0; i < relay_count_; ++i) {
      char num[10];
      const std::string_view p[1] = {number(epoch_, num)};
      emit_to(relays_[i].peer, relays_[i].id, MsgType::RELAY_DROP, p, 1);
    }
    if (relay_count_ + offered_count_ != 0) ++relay_rev_;
    relay_count_ = 0;
    offered_count_ = 0;
  }
  /// PANIC without a master: relay requests at once, standing after the back-off.
  void enter_panic() noexcept {
    clear_prevotes();
    if (!cfg_.election.enabled) return;
    relay_at_ = now_;
    stand_at_ = member_count_ > 0 && is_assigned_id(id_) ? now_ + backoff() : kNever;
  }
  /// Back-off before standing: backoff + score x backoff_step, spread by id (ties stand apart).
  Millis backoff() const noexcept {
    const std::uint32_t sc = score() < 1000u ? score() : 1000u;
    const Millis step = cfg_.timers[Timer::backoff_step];
    return cfg_.timers[Timer::backoff] + sc * step + (id_ % 16u) * step / 16u;
  }
  Millis election_due() const noexcept {
    if (!cfg_.election.enabled || state_ != State::PANIC) return kNever;
    const Millis r = role_ != Role::master ? relay_at_ : kNever;
    // Standing waits for the pre-votes too: without them the next event is a relay request's retry
    // or a PREVOTE_OK arriving, not the back-off's end.
    const Millis st = role_ != Role::master && member_count_ > 0 && prevote_quorum() ? stand_at_ : kNever;
    return r < st ? r : st;
  }
  void adopt_epoch(std::uint32_t e) noexcept {
    if (e > epoch_) {
      epoch_ = e;
      clear_prevotes();
      voted_for_ = 0;
      durable_changed();
    }
  }
  void durable_changed() noexcept {
    if (epoch_ == durable_.epoch && voted_for_ == durable_.voted_for) return;
    durable_ = Durable{epoch_, voted_for_};
    ++durable_rev_;
  }
  void set_role(Role r) noexcept {
    if (r == role_) return;
    if (r == Role::master) master_epoch_ = epoch_;
    role_ = r;
    if (r != Role::candidate) {
      if (vote_count_ != 0) ++relay_rev_;
      vote_count_ = 0;
    }
  }
  bool is_member(std::uint16_t id) const noexcept {
    for (std::size_t i = 0; i < member_count_; ++i)
      if (members_[i] == id) return true;
    return false;
  }
  static const PeerEntry* find(const PeerEntry* t, std::size_t n, std::uint16_t id) noexcept {
    for (std::size_t i = 0; i < n; ++i)
      if (t[i].id == id) return &t[i];
    return nullptr;
  }
  void add(PeerEntry* t, std::size_t& n, std::uint16_t id, Peer peer) noexcept {
    ++relay_rev_;
    for (std::size_t i = 0; i < n; ++i)
      if (t[i].id == id) {
        t[i].peer = peer;
        return;
      }
    if (n == RelaySlots) {  // full (offers only): the oldest is forgotten
      for (std::size_t i = 1; i < n; ++i) t[i - 1] = t[i];
      --n;
    }
    t[n++] = PeerEntry{id, peer};
  }
  void remove(PeerEntry* t, std::size_t& n, std::uint16_t id) noexcept {
    for (std::size_t i = 0; i < n; ++i)
      if (t[i].id == id) {
        for (std::size_t j = i + 1; j < n; ++j) t[j - 1] = t[j];
        --n;
        ++relay_rev_;
        return;
      }
  }
  /// The master's id for answers and reports: the one followed, else the PC.
  std::uint16_t master_id() const noexcept { return leader_ != 0 ? leader_ : kMasterId; }
  /// Runs internal action @p f as spec action @p a with a trace record.
  template <typename F>
  void traced(Action a, F&& f) noexcept {
    const AgentVars before = vars();
    f();
    record(a, before, {}, {}, 0);
  }

  // ------------------------------------------------------ behaviour, devices

  /// Spec ActionOkOk: Running.
  bool ActionOkOk() const noexcept { return Running(); }
  /// Spec ActionOk: ACTION_OK(step), next action. The cycle length is the caller's business: the
  /// step counts up (spec: modulo Steps, the model's bound).
  void ActionOk() noexcept {
    char num[10];
    const std::string_view p[1] = {number(step_, num)};
    emit(Dest::master, master_id(), MsgType::ACTION_OK, p, 1);
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
    emit(Dest::master, master_id(), MsgType::ACTION_INTERR, p, 2);
  }

  /// Spec ActionFailedOk: Running.
  bool ActionFailedOk() const noexcept { return Running(); }
  /// Spec ActionFailed: motors stop, ACTION_ERR(step, "error"), wait for RESTART.
  void ActionFailed() noexcept {
    wait_ = Wait::RESTART;
    motors_pause();
    char num[10];
    const std::string_view p[2] = {number(step_, num), "error"};
    emit(Dest::master, master_id(), MsgType::ACTION_ERR, p, 2);
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
    return emit(Dest::master, master_id(), MsgType::SENSOR_VALUE, p, count + 2);
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
      emit(Dest::master, master_id(), MsgType::EVENT, p, 1);
    }
  }

  /// Spec DevicePluggedOk: alive and a device missing.
  bool DevicePluggedOk() const noexcept { return state_ != State::OFF && !dev_ok(); }
  /// Spec DevicePlugged: EVENT(DEVICE_CONNECTED) when synced.
  void DevicePlugged() noexcept {
    if (is_synced(state_)) {
      const std::string_view p[1] = {"DEVICE_CONNECTED"};
      emit(Dest::master, master_id(), MsgType::EVENT, p, 1);
    }
  }

  /// Spec BatteryLowOk: alive.
  bool BatteryLowOk() const noexcept { return state_ != State::OFF; }
  /// Spec BatteryLow: EVENT(BATTERY_LOW) when synced, stop, OFF.
  void BatteryLow() noexcept {
    if (is_synced(state_)) {
      const std::string_view p[1] = {"BATTERY_LOW"};
      emit(Dest::master, master_id(), MsgType::EVENT, p, 1);
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
  /// A datagram to one peer (relay and election answers).
  bool emit_to(Peer peer, std::uint16_t to, MsgType type, const std::string_view* params,
               std::size_t count) noexcept {
    return emit_from(id_, Dest::peer, to, type, params, count, peer);
  }
  /// Encodes a new datagram (next msgid) into the output queue; the oldest is dropped when full.
  /// Relayed (via != 0), a datagram for the master travels inside RELAY(master, datagram) to the
  /// relay; the outer datagram carries the inner one's msgid.
  bool emit_from(std::uint16_t from, Dest dest, std::uint16_t to, MsgType type,
                 const std::string_view* params, std::size_t count, Peer peer = 0) noexcept {
    // When full, the slot written is the oldest one; encode_parts() writes nothing on refusal.
    TxSlot& s = tx_[(tx_head_ + tx_count_) % TxSlots];
    EncodeResult r = encode_parts(from, to, msgid_, static_cast<std::uint8_t>(type), params,
                                  count, s.bytes, TxBytes);
    if (!r.ok()) return false;
    if (dest == Dest::master && via_ != 0) {
      char inner[TxBytes];
      std::memcpy(inner, s.bytes, r.size);
      char num[10];
      const std::string_view p[2] = {number(to, num), std::string_view(inner, r.size)};
      r = encode_parts(from, via_, msgid_, static_cast<std::uint8_t>(MsgType::RELAY), p, 2, s.bytes,
                       TxBytes);
      if (!r.ok()) return false;
    }
    ++msgid_;
    push_slot(s, dest, peer, r.size);
    return true;
  }
  /// Queues @p bytes unchanged (a relay forwarding an inner datagram): no msgid of ours.
  void emit_raw(Dest dest, Peer peer, std::string_view bytes) noexcept {
    TxSlot& s = tx_[(tx_head_ + tx_count_) % TxSlots];
    if (bytes.size() > TxBytes) return;
    std::memcpy(s.bytes, bytes.data(), bytes.size());
    push_slot(s, dest, peer, bytes.size());
  }
  void push_slot(TxSlot& s, Dest dest, Peer peer, std::size_t size) noexcept {
    if (tx_count_ == TxSlots) {
      tx_head_ = (tx_head_ + 1) % TxSlots;
      --tx_count_;
      ++overflowed_;
    }
    s.dest = dest;
    s.peer = peer;
    s.size = size;
    ++tx_count_;
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
      r.cmd = cmd_;
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
  // Election.tla (fixed capacity, no heap).
  Role role_ = Role::none;
  std::uint32_t epoch_;
  std::uint16_t voted_for_;
  Durable durable_{epoch_, voted_for_};
  std::uint32_t durable_rev_ = 0;
  std::uint32_t master_epoch_ = 0;
  std::uint16_t leader_ = 0;
  std::uint32_t following_ = 0;
  std::uint16_t via_ = 0;
  PeerEntry relays_[RelaySlots] = {};
  std::size_t relay_count_ = 0;
  PeerEntry offered_[RelaySlots] = {};
  std::size_t offered_count_ = 0;
  std::uint16_t members_[kMaxMembers] = {};
  std::size_t member_count_ = 0;
  std::uint16_t votes_[kMaxMembers] = {};
  std::size_t vote_count_ = 0;
  std::uint16_t prevotes_[kMaxMembers] = {};  // PREVOTE_OK senders, for standing in prevote_epoch_ + 1
  std::size_t prevote_count_ = 0;
  std::uint32_t prevote_epoch_ = 0;
  std::uint16_t records_ = 0;
  std::uint32_t relay_rev_ = 0;
  Millis relay_at_ = kNever, stand_at_ = kNever;
  std::uint16_t cur_master_ = kMasterId;  // the sender FromMaster accepts for this datagram
  std::uint32_t cmd_epoch_ = 1;           // the epoch of the command being handled (bare: 1)
  Action cmd_ = Action::Ignore;           // ApplyCommand: the inner handler (trace)
  Message rx_;
  Message inner_;
};

}  // namespace ev3proto
