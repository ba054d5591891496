/// @file agent_types.hpp
/// @brief The agent core's values: its configuration (capabilities, the robot's check, timers,
///        the election), what it hands out (datagrams to send, events, the loaded behaviour, the
///        trace record of a step, what a datagram was taken by) and its timers' names. No heap.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "core.hpp"
#include "election/common.hpp"
#include "timers.hpp"
#include "wire.hpp"

namespace ev3proto {

/// A behaviour the robot can run and the devices it needs (bit mask of the robot's device bits).
struct BehaviourSpec {
  std::string_view name;      ///< Name as the master sends it in BEHAVIOUR ("explore").
  std::uint32_t devices = 0;  ///< Device bits it needs (see Capabilities::devices).
};

/// The robot's own reason for refusing a BEHAVIOUR request (its check on receipt), carried in NOT:
/// "line 4 col 12: unknown action 'trun' (...)". Bounded (no heap): a longer reason keeps its first
/// kMax - 3 bytes (never half a UTF-8 character) and ends with "...", so that the NOT, escaped, fits
/// the agent's datagram.
struct CheckReason {
  static constexpr std::size_t kMax = 120; ///< bytes kept
  char text[kMax] = {};
  std::uint8_t len = 0;
  /// The reason.
  std::string_view view() const noexcept { return std::string_view(text, len); }
  /// Replaces the reason with @p s (cut as above when longer than kMax).
  void set(std::string_view s) noexcept {
    std::size_t n = s.size();
    const bool cut = n > kMax;
    if (cut) {
      n = kMax - 3;
      while (n > 0 && (static_cast<unsigned char>(s[n]) & 0xC0u) == 0x80u) --n;  // s[n] starts a character
    }
    if (n != 0) std::memcpy(text, s.data(), n);
    if (cut) {
      std::memcpy(text + n, "...", 3);
      n += 3;
    }
    len = static_cast<std::uint8_t>(n);
  }
};

/// The robot's check of a BEHAVIOUR request on receipt, before the agent answers (spec
/// AgentLogic RecvBehaviour, Refused): the name and the params after it as they came; true to
/// accept, false to refuse with the reason written in @p why. The robot program joins it to the
/// robot runtime (robot_link.hpp: parse, arguments, checker on the robot's model). No I/O, no heap.
struct BehaviourCheck {
  using Fn = bool (*)(void* ctx, std::string_view name, const std::string_view* params, std::size_t count,
                      CheckReason& why) noexcept;
  Fn fn = nullptr;     ///< nullptr: every behaviour of the table passes (no robot behind the core)
  void* ctx = nullptr; ///< passed to fn (the runtime); must outlive the agent
  /// The verdict on @p name with @p params: true when there is no check or it accepts.
  bool operator()(std::string_view name, const std::string_view* params, std::size_t count,
                  CheckReason& why) const noexcept {
    return fn == nullptr || fn(ctx, name, params, count, why);
  }
};

/// What a robot can do, fixed at construction: its model, its behaviours, its devices.
struct Capabilities {
  std::string_view model;                   ///< Model announced in AGENT ("A").
  const BehaviourSpec* behaviours = nullptr; ///< Behaviours it implements.
  std::size_t behaviour_count = 0;          ///< Entries of @c behaviours.
  std::uint32_t devices = 0;                ///< Device bits of the model, all plugged at start.
  /// The name of each device bit (index: the bit; "colour sensor"), for NOT "missing device: the
  /// robot has no colour sensor (explore needs it)"; a bit without a name gets "missing device".
  const std::string_view* device_names = nullptr;
  std::size_t device_name_count = 0;        ///< Entries of @c device_names.
};

/// NOT "missing device" naming what is missing for behaviour @p b on a robot of @p caps with
/// devices @p plugged: the first device @p b needs that is missing, else the first of the model's:
/// "missing device: the robot has no colour sensor (explore needs it)", "... (no behaviour runs
/// until it is back)". False, @p out untouched, when that device has no name (then the reason is
/// just "missing device").
inline bool name_missing_device(const Capabilities& caps, std::uint32_t plugged, const BehaviourSpec& b,
                                CheckReason& out) noexcept {
  const std::uint32_t needed = b.devices & ~plugged;
  const std::uint32_t missing = needed != 0 ? needed : caps.devices & ~plugged;
  std::size_t bit = 0;
  while (bit < 32 && (missing & (1u << bit)) == 0) ++bit;
  if (bit >= caps.device_name_count) return false;
  char buf[CheckReason::kMax + 1];
  std::size_t n = 0;
  auto put = [&buf, &n](std::string_view t) {
    for (const char c : t)
      if (n < sizeof buf) buf[n++] = c;
  };
  put(to_string(Refusal::missing_device));
  put(": the robot has no ");
  put(caps.device_names[bit]);
  if (needed != 0) {
    put(" (");
    put(b.name);
    put(" needs it)");
  } else {
    put(" (no behaviour runs until it is back)");
  }
  out.set(std::string_view(buf, n));
  return true;
}

/// Construction parameters of an Agent.
struct AgentConfig {
  Capabilities caps;             ///< Behaviours and devices (the table must outlive the agent).
  BehaviourCheck check;          ///< The robot's check of a BEHAVIOUR on receipt (none: all pass).
  Timers timers;                 ///< Deadlines (timers.hpp); the agent uses sync, heartbeat, loss,
                                 ///< paused, relay_retry, backoff, backoff_step, candidate.
  std::uint16_t temp_id = 50000; ///< Temporary id drawn at random by the caller (50000..65535).
  std::uint32_t first_msgid = 1; ///< msgid of the first datagram the agent sends.
  ElectionConfig election;       ///< Relay and election (off by default).
  std::size_t report_limit = 0;  ///< Reports held at most (Reports.tla Cap): 0 = the ReportSlots template
                                 ///< parameter; at most that (reports.hpp ReportBuffer::set_limit)
  std::size_t window = 0;        ///< Dedupe window entries (spec Window): 0 = the Window template
                                 ///< argument; at most that (one compiled core serves every size).
};

/// The answer recorded in the dedupe window for a command: sent again for a duplicate.
struct StoredAnswer {
  std::uint16_t src = 0;                      ///< Sender id the answer was sent with.
  std::uint32_t ref = 0;                      ///< The answered msgid.
  bool ack = true;                            ///< ACK (true) or NOT (false).
  Refusal reason = Refusal::wrong_state;      ///< NOT's reason (unless the check refused).
  CheckReason check;                          ///< NOT's words when not @c reason's spelling: the
                                              ///< robot's check's, or the missing device named.
  /// NOT's reason as sent: the check's words, or the spelling of @c reason.
  std::string_view reason_text() const noexcept { return check.len != 0 ? check.view() : to_string(reason); }
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
  /// (Election changes are observers here, Agent::role(), Agent::durable(); the node reports them
  /// as events: node.hpp.)
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

/// The behaviour BEHAVIOUR loaded (spec beh): its name and arguments in fixed storage.
/// @tparam NameBytes longest name; @tparam ArgBytes all arguments' bytes; @tparam MaxArgs most arguments.
template <std::size_t NameBytes, std::size_t ArgBytes, std::size_t MaxArgs>
class LoadedBehaviour {
 public:
  /// True when BEHAVIOUR @p m's name and arguments fit.
  static bool fits(const Message& m) noexcept {
    if (m.param(0).size() > NameBytes || m.param(0).empty() || m.param_count() - 1 > MaxArgs) return false;
    std::size_t bytes = 0;
    for (std::size_t i = 1; i < m.param_count(); ++i) bytes += m.param(i).size();
    return bytes <= ArgBytes;
  }
  /// Keeps BEHAVIOUR @p m's name and arguments (fits(m) holds).
  void load(const Message& m) noexcept {
    const std::string_view n = m.param(0);
    std::memcpy(name_, n.data(), n.size());
    len_ = n.size();
    std::size_t used = 0;
    count_ = 0;
    for (std::size_t i = 1; i < m.param_count(); ++i) {
      const std::string_view a = m.param(i);
      if (!a.empty()) std::memcpy(args_ + used, a.data(), a.size());
      used += a.size();
      ends_[count_++] = static_cast<std::uint16_t>(used);
    }
  }
  /// None loaded (spec NoBehaviour).
  void unload() noexcept { len_ = count_ = 0; }
  /// True when one is loaded.
  bool loaded() const noexcept { return len_ != 0; }
  /// Its name ("" when none).
  std::string_view name() const noexcept { return std::string_view(name_, len_); }
  /// Name and arguments.
  BehaviourView view() const noexcept { return BehaviourView{name(), args_, ends_, count_}; }

 private:
  char name_[NameBytes] = {};
  std::size_t len_ = 0;
  char args_[ArgBytes] = {};
  std::uint16_t ends_[MaxArgs] = {};
  std::size_t count_ = 0;
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
  ElectionRole role = ElectionRole::none;    ///< With state: Election life (CANDIDATE, MASTER are PANIC + role).
  std::uint32_t epoch = 1;   ///< epoch
  std::uint16_t voted_for = 0; ///< votedFor (0 = NoNode)
  std::uint16_t leader = 0;  ///< leader (0 = NoNode)
  std::uint32_t following = 0; ///< following
  std::uint16_t via = 0;     ///< via (0 = NoNode)
  std::uint32_t relay_rev = 0; ///< changes whenever relays / offered / votes change
  std::uint32_t mepoch = 0;    ///< Election mepoch: the epoch that published the membership
  std::uint32_t floor = 0;     ///< Election floor
  std::uint32_t members_rev = 0; ///< changes whenever the membership (Election members) may change
  /// The next msgid (not a spec variable): a record that sent datagrams moved it, so the trace
  /// names the msgids each record sent (the merge of a run's traces, docs/spec.md "Whole-run traces").
  std::uint32_t msgid = 0;
  /// Reports.tla's made and lo (not AgentLogic's): the reports made, the lowest number still held.
  std::uint32_t made = 0, lo = 1;
  /// The behaviour name.
  std::string_view beh_name() const noexcept { return std::string_view(beh, beh_len); }
};

/// One trace record: a spec action the agent took, its arguments, and the variables around it.
struct AgentTraceRecord {
  Action action = Action::Tick; ///< The spec action (handler) taken.
  std::string_view msg;         ///< Receive handlers: the datagram as received.
  std::string_view event;       ///< ActionInterrupted: the warning name; RobotEvent: the event's.
  std::string_view port;        ///< DeviceUnplugged, DevicePlugged, RobotEvent: the port.
  std::string_view check;       ///< RecvBehaviour (also inside ApplyCommand): the reason the robot's
                                ///< check refused the request with ("" if it accepted or was not asked).
  Millis ticks = 0;             ///< Tick: number of consecutive spec Ticks this record stands for.
  Millis now = 0;               ///< Time after the action.
  Action cmd = Action::Ignore;  ///< ApplyCommand: the receive handler that took the inner datagram.
  AgentVars before;             ///< Variables before.
  AgentVars after;              ///< Variables after.
};

/// What handle_datagram() did with one datagram: the spec action taken, or why none was.
struct Handled {
  Action action = Action::Ignore; ///< The spec action taken (Ignore: none; see why).
  Ignored why = Ignored::no;      ///< Why no action took it (Ignored::no when one did).
  Action inner = Action::Ignore;  ///< ApplyCommand: the receive handler of the inner datagram.
  DecodeResult decode;            ///< Ignored::undecodable: the codec's reason and field.
  /// True when a spec action took the datagram.
  bool taken() const noexcept { return why == Ignored::no; }
};

/// The agent core's armed deadlines (one TimerTable entry each).
enum class AgentTimer : std::uint8_t {
  periodic,  ///< The heartbeat phase completes: AGENT / PING / PANIC (spec clk wraps).
  lifecycle, ///< SyncTimeout (IDLE) or HeartbeatLost (ACTIVE, WORKING: loss; PAUSED: paused).
  relay,     ///< PANIC: the next RELAY_REQ (Election RequestRelay).
  stand,     ///< PANIC with a pre-vote quorum: the back-off is over (Election StartElection).
};
/// Number of agent timers.
inline constexpr std::size_t kAgentTimerCount = 4;
/// The timers the agent's TimerTable holds (relay and stand are the election's: AgentElection).
inline constexpr std::size_t kAgentTableTimers = 2;

}  // namespace ev3proto
