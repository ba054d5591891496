/// @file master_types.hpp
/// @brief The master core's values: its configuration (MasterConfig, the elected agent's too),
///        what it hands out (operator events, datagrams to send, the trace record of a step, what
///        a datagram was taken by and why it was ignored) and the desired-state rule of
///        MasterLogic (desired_after).
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "core.hpp"
#include "messages.hpp"
#include "msgids.hpp"
#include "reports.hpp"
#include "timers.hpp"
#include "wire.hpp"

namespace ev3proto {

/// Construction parameters of a Master.
struct MasterConfig {
  Timers timers;                 ///< Deadlines (timers.hpp); resend and drop are used.
  std::uint16_t next_id = kFirstAssignedId; ///< First id to assign (stable storage across restarts).
  std::uint32_t next_msgid = 1;  ///< msgid of the first datagram (stable storage across restarts).
  std::uint32_t max_resends = 10; ///< An operator command unanswered after this many resends fails.
  // Relay and election (spec/tla/Election.tla, docs/core.md). Off by default: Fleet.tla's master.
  bool election = false;          ///< LEADER heartbeats, epochs, EPOCH_CMD, relay routes, step-down.
  std::uint32_t epoch = 1;        ///< The epoch (persisted; an elected agent: the epoch it won).
  std::uint16_t self_id = kMasterId; ///< The master's id: 1 (PC) or the elected agent's id.
  std::vector<std::uint16_t> members; ///< The membership of epoch members_epoch (persisted): LEADER
                                      ///< carries it, votes count against it (Election members[PC]).
  std::uint32_t members_epoch = 0; ///< The epoch that published it (persisted; 0: `epoch`).
  bool candidate = false;         ///< Start as a candidate (the PC back after a crash: Restart(PC)).
  /// Ignore a copy of a (sender, msgid) already taken (MasterReceipt: duplicate), in a window of
  /// the last 4096. Off by default: MasterLogic has no window, every copy goes through its handler
  /// (the conformance driver). Programs turn it on: each datagram arrives 3 times.
  bool drop_copies = false;
  /// Hold every datagram while the durable state (MasterDurable: next_id, epoch, the membership
  /// published, the msgid block) changed and ready() has not had it written. Off by default (the
  /// drivers and transcripts poll datagrams alone); programs with stable storage turn it on.
  bool durable_first = false;
  /// Keep the record of reports for ready(write, append, send) (OperatorEvent::recorded), and
  /// hold every datagram until it is appended: a REPORT_ACK never covers a report the program has
  /// not stored. Off by default (the record is then the operator events and report_records()).
  bool keep_record = false;
  /// The record of reports restored from stable storage, per agent (a restarted PC continues each
  /// agent's record where it ends, and never hands out the id of an agent it has a record of:
  /// next_id is raised above them).
  std::map<std::uint16_t, ReportRecord> records;

  /// The configuration for an agent that won epoch @p epoch with membership @p members (see
  /// Agent::master_epoch()): no new ids (AGENT from a temporary id is ignored), msgids from
  /// elected_master_first_msgid(@p epoch): disjoint from the agent core's, and above those of every
  /// epoch this node won before, also across its restarts (msgids.hpp).
  static MasterConfig for_elected_agent(const Timers& t, std::uint16_t self, std::uint32_t epoch,
                                        std::vector<std::uint16_t> members) {
    MasterConfig c;
    c.timers = t;
    c.next_id = kLastAssignedId + 1;
    c.next_msgid = elected_master_first_msgid(epoch);
    c.election = true;
    c.epoch = epoch;
    c.self_id = self;
    c.members = std::move(members);
    c.members_epoch = epoch;  // the list it counted its votes against is the one of its epoch
    return c;
  }
};

/// Something the operator (UI, log, mission logic) should know.
struct OperatorEvent {
  /// What happened.
  enum class Kind : std::uint8_t {
    registered,    ///< An agent acknowledged MASTER: synced with id @c agent.
    acked,         ///< @c command was acknowledged by @c agent.
    refused,       ///< @c command was refused by @c agent with @c text (the reason).
    timed_out,     ///< @c command got no answer after max_resends resends (or the agent dropped).
    unknown_agent, ///< A command named an id that is not registered.
    dropped,       ///< @c agent was not heard for the drop timeout and left the registry.
    state,         ///< @c agent reported a new state in PING (@c text).
    report,        ///< A report (ACTION_OK, ACTION_INTERR, ACTION_ERR, SENSOR_VALUE, EVENT): @c text;
                   ///< numbered (@c seq) when it came in REPORT and was recorded.
    reports_dropped, ///< Numbers @c seq..@c last of @c agent recorded as dropped by its bound.
    reports_skipped, ///< Numbers @c seq..@c last the agent no longer held when offered here.
  } kind = Kind::state;
  std::uint16_t agent = 0;             ///< The agent's id.
  MsgType command = MsgType::START;    ///< The command (acked, refused, timed_out, unknown_agent) or
                                       ///< the report's type.
  std::string text;                    ///< Reason, state, or the report's params joined by ':'.
  std::uint32_t seq = 0;               ///< A recorded report's number (0: not numbered), or the
                                       ///< first number of reports_dropped / reports_skipped.
  std::uint32_t last = 0;              ///< The last number of reports_dropped / reports_skipped.
  std::uint32_t tag = 0;               ///< acked, refused, timed_out, unknown_agent: the command's
                                       ///< Command::tag (0: a command the core made, reconcile's).
  /// Part of the record of reports (a numbered report, a drop, a skip): what a PC master keeps.
  bool recorded() const noexcept {
    return (kind == Kind::report && seq != 0) || kind == Kind::reports_dropped || kind == Kind::reports_skipped;
  }
};

/// Spelling of an operator event kind ("refused").
constexpr std::string_view to_string(OperatorEvent::Kind k) noexcept {
  switch (k) {
    case OperatorEvent::Kind::registered: return "registered";
    case OperatorEvent::Kind::acked: return "acked";
    case OperatorEvent::Kind::refused: return "refused";
    case OperatorEvent::Kind::timed_out: return "timed_out";
    case OperatorEvent::Kind::unknown_agent: return "unknown_agent";
    case OperatorEvent::Kind::dropped: return "dropped";
    case OperatorEvent::Kind::state: return "state";
    case OperatorEvent::Kind::report: return "report";
    case OperatorEvent::Kind::reports_dropped: return "reports_dropped";
    case OperatorEvent::Kind::reports_skipped: return "reports_skipped";
  }
  return {};
}

/// A datagram the master wants sent (unicast to a peer).
struct MasterTransmit {
  Peer peer = 0;      ///< Destination (Dest::peer).
  Dest dest = Dest::peer; ///< peer, or broadcast (ELECT, LEADER: election only).
  std::string bytes;  ///< The encoded datagram (send it 3 times, as the transport does).
};

/// The state the operator last asked an agent to be in (MasterLogic DesiredAfter): START/RESUME ->
/// WORKING, PAUSE -> PAUSED, STOP/STANDBY -> ACTIVE; other commands keep it.
constexpr AgentState desired_after(MsgType command, AgentState desired) noexcept {
  switch (command) {
    case MsgType::START:
    case MsgType::RESUME: return AgentState::WORKING;
    case MsgType::PAUSE: return AgentState::PAUSED;
    case MsgType::STOP:
    case MsgType::STANDBY: return AgentState::ACTIVE;
    default: return desired;
  }
}

/// True for the commands that set the desired state (START, RESUME, PAUSE, STOP, STANDBY).
constexpr bool sets_desired(MsgType command) noexcept {
  return desired_after(command, AgentState::IDLE) != AgentState::IDLE;
}

/// Why the master ignored a datagram, or why the action that took it changed nothing. The
/// spellings are the programs' drop counters.
enum class MasterIgnored : std::uint8_t {
  none,            ///< Taken, and acted on.
  malformed,       ///< Does not decode (MasterReceipt::reason); no spec step.
  misaddressed,    ///< Receiver neither this master nor broadcast (spec Handler: Ignore).
  duplicate,       ///< A copy of a (sender, msgid) already taken (MasterConfig::drop_copies), or
                   ///< of a report already passed on (MasterReport, no operator event).
  unexpected_type, ///< A type the master has no handler for (MASTER, PONG, a command; the
                   ///< election's types with election off).
  own_broadcast,   ///< Our own LEADER / ELECT heard back (election).
  not_master,      ///< Fleet traffic while CANDIDATE or stepped down (election).
  not_enabled,     ///< An election datagram whose Election.tla rule is not enabled (epoch, role,
                   ///< receiver, membership), or a RELAY not to us / inside a RELAY.
  unknown_sender,  ///< MasterAnswer / MasterPing / MasterReport from an id not registered: the
                   ///< spec step is taken and changes nothing (no PONG; a report is still shown).
  stale_answer,    ///< MasterAnswer: ACK / NOT of no pending msgid (a copy, a late answer, a NOT
                   ///< to MASTER): only the highest msgid heard moves.
  ids_exhausted,   ///< MasterSync: a new agent, and no id left to give (or an elected agent's
                   ///< master, which gives none).
  bad_report,      ///< REPORT / REPORT_DROPPED not from an assigned id, with invalid numbers, or
                   ///< without a report of its sender inside.
};

/// The drop counter's spelling of @p i ("unknown_sender").
constexpr std::string_view to_string(MasterIgnored i) noexcept {
  switch (i) {
    case MasterIgnored::none: return "none";
    case MasterIgnored::malformed: return "malformed";
    case MasterIgnored::misaddressed: return "misaddressed";
    case MasterIgnored::duplicate: return "duplicate";
    case MasterIgnored::unexpected_type: return "unexpected_type";
    case MasterIgnored::own_broadcast: return "own_broadcast";
    case MasterIgnored::not_master: return "not_master";
    case MasterIgnored::not_enabled: return "not_enabled";
    case MasterIgnored::unknown_sender: return "unknown_sender";
    case MasterIgnored::stale_answer: return "stale_answer";
    case MasterIgnored::ids_exhausted: return "ids_exhausted";
    case MasterIgnored::bad_report: return "bad_report";
  }
  return {};
}

/// What Master::handle_datagram / handle_message did with a datagram.
struct MasterReceipt {
  Action action = Action::Ignore; ///< The spec action taken (its trace record was written), or Ignore.
  MasterIgnored why = MasterIgnored::none;    ///< Ignore: why. With an action: why it changed nothing, else none.
  Reason reason = Reason::ok;     ///< why == malformed: the decoder's reason.

  /// True when a spec action took the datagram.
  bool taken() const noexcept { return action != Action::Ignore; }
};

/// One trace record of the master: a spec action, its message, and the master's variables.
struct MasterTraceRecord {
  Action action = Action::MasterTick; ///< MasterSync, MasterAnswer, MasterPing, MasterTick,
                                      ///< MasterCommand, MasterReport (and the election's).
  std::string_view msg;       ///< The datagram received (receive actions).
  Millis now = 0;             ///< Time.
  std::string reg_before;     ///< Registry (spec master.reg) as JSON, before.
  std::string reg_after;      ///< Registry as JSON, after.
  std::uint16_t next_id_before = 0, next_id_after = 0;   ///< master.nextId
  std::uint32_t msgid_before = 0, msgid_after = 0;       ///< master.msgid
  std::string_view life_before, life_after;             ///< Election life (MASTER, CANDIDATE...)
  std::uint32_t epoch_before = 0, epoch_after = 0;      ///< Election epoch
  std::string votes_before, votes_after;                ///< Election votes ([ids])
  std::string members_before, members_after;            ///< Election members (of the epoch, [ids])
  std::uint32_t mepoch_before = 0, mepoch_after = 0;    ///< Election mepoch
  std::uint16_t rec_agent = 0;                          ///< PCTake: the agent whose record it is (0: none)
  std::uint32_t rec_before = 0, rec_after = 0;          ///< PCTake: its last number recorded (Reports.tla)
};

}  // namespace ev3proto
