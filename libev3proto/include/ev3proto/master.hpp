/// @file master.hpp
/// @brief The master's protocol state machine of spec/tla/MasterLogic.tla (MasterSync, MasterAnswer,
///        MasterPing, MasterReport, MasterCommand, MasterTick), with no I/O.
///
/// Sans-I/O like the agent: datagrams, time and operator commands in; datagrams (to peer handles),
/// operator events and the next deadline out. The master runs on a PC (or a robot acting as one),
/// so it may allocate. Ids 2..49999 are handed out in order and never reused within a run; pass the
/// last run's next_id / next_msgid back in (stable storage) after a restart, as MasterLogic's
/// CrashMaster keeps nextId and msgid: ready(write, send) hands them over (MasterDurable, with a
/// reserved msgid block) before the datagrams that depend on them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <algorithm>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "core.hpp"
#include "deadline_list.hpp"
#include "dedupe.hpp"
#include "durable.hpp"
#include "election/master.hpp"
#include "json.hpp"
#include "master_registry.hpp"
#include "master_types.hpp"
#include "messages.hpp"
#include "msgids.hpp"
#include "record.hpp"
#include "timers.hpp"
#include "wire.hpp"

namespace ev3proto {

/// The master core.
///
/// Every MasterLogic.tla / Election.tla action the master performs has a const guard `XOk(...)`,
/// taking what it needs as parameters, and a handler `X` of the same name as the spec action. The
/// entry points (handle_datagram / handle_message, advance, command) pick the action, run it and
/// write its trace record; role changes happen only in become_master / become_candidate /
/// become_stepped_down. Per-entry deadlines (drop, resend) live in two DeadlineLists: handling a
/// datagram, advance() and next_deadline() never walk the registry.
/// @tparam Trace NoTrace (default) or a sink with `void record(const MasterTraceRecord&)`.
template <typename Trace = NoTrace>
class Master {
 public:
  /// "No deadline".
  static constexpr Millis kNever = ~Millis{0};

  /// A master with an empty registry at time @p now.
  Master(const MasterConfig& config, Millis now, Trace* trace = nullptr)
      : cfg_(config), trace_(trace), next_id_(config.next_id), msgid_(config.next_msgid), now_(now),
        drops_(config.timers[Timer::drop]), resends_(config.timers[Timer::resend]), copies_(config.drop_copies),
        el_(config.election, config.epoch, config.self_id, config.members, config.members_epoch, config.timers) {
    records_ = cfg_.records;
    cfg_.records.clear();  // kept once, in records_
    for (const auto& kv : records_)  // a recorded agent's id is never handed out again
      if (is_assigned_id(kv.first) && next_id_ <= kv.first) next_id_ = static_cast<std::uint16_t>(kv.first + 1);
    if (!cfg_.election) return;  // Fleet.tla's master: MASTER for good, no LEADER
    if (config.candidate) {
      el_.become_candidate(now_);  // Restart(PC): stands at once
    } else {
      el_.become_master();
      el_.hb_at = now_;  // LEADER at once
    }
  }

  // ---------------------------------------------------------------- inputs

  /// Time moves to @p now: every deadline due up to then is acted on at its own time, one spec
  /// step each (Heartbeat, StartElection, or MasterTick of the entries due then).
  void advance(Millis now) {
    for (;;) {
      if (take_role_steps()) continue;  // the PC's first step needs no vote: it wins as it stands
      const Millis t = next_deadline();
      if (t > now || t == kNever) break;
      Snapshot s = snap();  // before time moves: MasterTick's record shows quiet growing
      if (t > now_) now_ = t;
      if (el_.HeartbeatOk(now_)) {
        el_.Heartbeat(*this);
        record(Action::Heartbeat, s, {});
      } else if (el_.StartElectionOk(now_)) {
        el_.StartElection(*this);
        record(Action::StartElection, s, {});
      } else if (MasterTickOk(now_)) {
        MasterTick();
        record(Action::MasterTick, s, {});
      } else {
        break;  // not reached: next_deadline() is one of the three
      }
    }
    if (now > now_) now_ = now;
  }

  /// A datagram arrived from @p from at @p now (spec Receive). Returns the action taken, or why
  /// the datagram was ignored (MasterReceipt): a datagram that does not decode is no spec step
  /// (counted in rejected()).
  MasterReceipt handle_datagram(std::string_view bytes, Peer from, Millis now) {
    advance(now);
    const DecodeResult d = decode(bytes, rx_);
    if (!d.ok()) {
      ++rejected_;
      return MasterReceipt{Action::Ignore, MasterIgnored::malformed, d.reason};
    }
    return take(rx_, bytes, from);
  }

  /// The same for a datagram the caller has decoded already (a node that runs an agent core too
  /// decodes once): @p m decoded from @p bytes (the trace records the bytes).
  MasterReceipt handle_message(const Message& m, std::string_view bytes, Peer from, Millis now) {
    advance(now);
    return take(m, bytes, from);
  }

  /// An operator command for agent @p agent (0 = every registered agent) at @p now. Queued behind
  /// the agent's pending command; sent at once when none is pending; the agent's desired state
  /// follows it (desired_after). Unknown ids are reported (the spec step changes nothing).
  /// Returns the agents it was queued for, in id order (none: an unknown id, or 0 with no agent).
  std::vector<std::uint16_t> command(std::uint16_t agent, const Command& c, Millis now) {
    advance(now);
    Snapshot s = snap();
    std::vector<std::uint16_t> to;
    if (MasterCommandOk(agent))
      MasterCommand(agent, c, to);
    else
      push(OperatorEvent::Kind::unknown_agent, agent, c.type, {}, c.tag);
    record(Action::MasterCommand, s, {});
    return to;
  }

  // ---------------------------------------------------------------- outputs

  /// What the calls since the last ready() left for the program, in the order it must be done (as
  /// etcd raft's Ready): first @p write gets the durable state when it changed since the last write
  /// (`bool write(const MasterDurable&)`: true once it is on stable storage), then @p send gets every
  /// datagram (`void send(const MasterTransmit&)`). The durable state changes with next_id, the
  /// epoch, the membership published (members(), members_epoch()), and when less than half of
  /// the reserved msgid block is left: its next_msgid is the end of a block of kMsgidBlock msgids
  /// reserved from next_msgid() on (MsgidReservation), so a master restarted from it continues
  /// above every msgid it sent. The first ready() always writes. When @p write fails, nothing is
  /// sent and false is returned: the datagrams stay queued and the next ready() writes again first.
  template <typename Write, typename Send>
  bool ready(Write&& write, Send&& send) {
    record_.clear();  // no record kept by this caller: the operator events carry it
    return ready(write, [](const std::vector<OperatorEvent>&) { return true; }, send);
  }
  /// ready() for a PC that keeps the record of reports (MasterConfig::keep_record): after the
  /// durable state and before any datagram, @p append gets the record's new entries
  /// (`bool append(const std::vector<OperatorEvent>&)`: true once they are on stable storage);
  /// when it fails, nothing is sent and false is returned (the entries are offered again).
  template <typename Write, typename Append, typename Send>
  bool ready(Write&& write, Append&& append, Send&& send) {
    if (durable_due()) {
      MasterDurable d = durable();
      d.next_msgid = MsgidReservation(reserved_).reserve(msgid_);
      if (!write(static_cast<const MasterDurable&>(d))) return false;
      reserved_.reserve(msgid_);
      written_id_ = next_id_;
      written_epoch_ = el_.epoch;
      written_members_.assign(d.members, d.members + d.member_count);
      written_mepoch_ = d.members_epoch;
      written_rev_ = el_.members_rev;
      written_ = true;
    }
    if (!record_.empty()) {
      if (!append(static_cast<const std::vector<OperatorEvent>&>(record_))) return false;
      record_.clear();
    }
    MasterTransmit t;
    while (poll_transmit(t)) send(static_cast<const MasterTransmit&>(t));
    return true;
  }

  /// Takes the oldest datagram to send; false when there is none, and with
  /// MasterConfig::durable_first while ready() has a durable state to write first. Programs call
  /// ready(); this is the step below it.
  bool poll_transmit(MasterTransmit& out) {
    if (tx_.empty() || (cfg_.durable_first && durable_due()) || !record_.empty()) return false;
    out = std::move(tx_.front());
    tx_.pop_front();
    return true;
  }

  /// Takes the oldest operator event; false when there is none.
  bool poll_event(OperatorEvent& out) {
    if (ev_.empty()) return false;
    out = std::move(ev_.front());
    ev_.pop_front();
    return true;
  }

  /// When advance() must be called next at the latest (kNever when nothing is scheduled): the
  /// earliest of the LEADER heartbeat, the candidate's next election and (as MASTER) the entries'
  /// deadlines, the fronts of two DeadlineLists (O(1) here, no walk of the registry).
  Millis next_deadline() const noexcept {
    Millis t = el_.hb_at < el_.StandDeadline() ? el_.hb_at : el_.StandDeadline();
    if (el_.role != MasterRole::master) return t;
    const Millis e = entries_due();
    return e < t ? e : t;
  }

  // ---------------------------------------------------------------- observers

  /// The registry, by assigned id.
  const std::map<std::uint16_t, RegistryEntry>& registry() const noexcept { return reg_.map(); }
  /// What this master recorded of each agent's reports (Reports.tla rec, nx), by id.
  const std::map<std::uint16_t, ReportRecord>& report_records() const noexcept { return records_; }
  /// The next id to assign (persist it).
  std::uint16_t next_id() const noexcept { return next_id_; }
  /// The next msgid (persist it).
  std::uint32_t next_msgid() const noexcept { return msgid_; }
  /// The master's time.
  Millis now() const noexcept { return now_; }
  /// Datagrams that did not decode.
  std::uint32_t rejected() const noexcept { return rejected_; }
  /// Election role (MASTER, CANDIDATE, stepped down).
  MasterRole role() const noexcept { return el_.role; }
  /// The epoch (persist it with next_id / next_msgid).
  std::uint32_t epoch() const noexcept { return el_.epoch; }
  /// The master's id (1, or the elected agent's).
  std::uint16_t self_id() const noexcept { return el_.self; }
  /// The fleet the master wants (Election want, the PC's registry): the membership of its epoch,
  /// the members handed over, and every agent registered and synced since. The PC changes the
  /// membership it publishes towards it one agent per epoch (Reconfigure); an agent declared lost
  /// (DropMember) is no longer wanted until it syncs again.
  std::vector<std::uint16_t> want() const {
    const std::set<std::uint16_t>& m = el_.Want(reg_);
    return std::vector<std::uint16_t>(m.begin(), m.end());
  }
  /// The membership of the master's epoch (persist it with members_epoch()): LEADER carries it,
  /// votes count against it (Election members[PC]).
  std::vector<std::uint16_t> members() const {
    return std::vector<std::uint16_t>(el_.members.begin(), el_.members.end());
  }
  /// The epoch that published it (Election mepoch[PC]).
  std::uint32_t members_epoch() const noexcept { return el_.mepoch; }
  /// What to keep on stable storage (durable.hpp: next_id, next_msgid, epoch, the membership
  /// published and its epoch), next_msgid as it is now (ready() writes the end of a reserved block).
  MasterDurable durable() const {
    MasterDurable d;
    d.next_id = next_id_;
    d.next_msgid = msgid_;
    d.epoch = el_.epoch;
    d.members_epoch = el_.mepoch;
    for (std::uint16_t id : el_.members)
      if (d.member_count < kMaxMembership) d.members[d.member_count++] = id;
    return d;
  }
  /// Changes whenever want() or members() may have changed (a program persisting the
  /// membership compares this instead of building it after every datagram).
  std::uint64_t members_rev() const noexcept { return el_.members_rev; }
  /// True once this (elected agent's) master handed its registry over (HANDOVER sent).
  bool handed_over() const noexcept { return el_.handed_over; }
  /// Relay and election on (MasterConfig::election).
  bool election() const noexcept { return cfg_.election; }
  /// The votes counted as a candidate in this epoch (Election votes[n]).
  std::vector<std::uint16_t> votes() const { return std::vector<std::uint16_t>(el_.votes.begin(), el_.votes.end()); }

 private:
  friend MasterElection;  // its transitions send through broadcast and send

  // ------------------------------------------------ receive: the spec's Handler(m)

  /// Takes @p m: dispatch, its trace record, then the role steps it enabled (take_role_steps).
  MasterReceipt take(const Message& m, std::string_view bytes, Peer from) {
    Snapshot s = snap();
    const MasterReceipt r = Dispatch(m, from, 0);
    // A relay's RELAY(master, datagram) is taken as the datagram inside: the record is of that one.
    if (r.action != Action::Ignore) record(r.action, s, m.type == MsgType::RELAY ? m.param(1) : bytes);
    while (take_role_steps()) {
    }
    return r;
  }

  /// The role steps that need no input, one at a time, each with its record: BecomeMaster when a
  /// vote completed a majority (or the fresh PC stands), else Reconfigure when an agent synced or
  /// was handed over. False when neither is enabled.
  bool take_role_steps() {
    const bool become = el_.BecomeMasterOk();
    if (!become && !el_.ReconfigureOk(reg_)) return false;
    Snapshot s = snap();
    if (become) {
      el_.BecomeMaster(*this, reg_);
      record(Action::BecomeMaster, s, {});
    } else {
      el_.Reconfigure(now_);
      record(Action::Reconfigure, s, {});
    }
    return true;
  }

  static MasterReceipt taken(Action a, MasterIgnored why = MasterIgnored::none) noexcept { return MasterReceipt{a, why}; }
  static MasterReceipt ignored(MasterIgnored why) noexcept { return MasterReceipt{Action::Ignore, why}; }

  /// Takes @p m from @p from (through relay @p via, 0 = direct): Election.tla's rules first (with
  /// election on), then MasterLogic's Handler(m).
  MasterReceipt Dispatch(const Message& m, Peer from, std::uint16_t via) {
    if (m.receiver != el_.self && m.receiver != kBroadcastId) return ignored(MasterIgnored::misaddressed);
    if (via == 0 && !copies_.first_time(m.sender, m.msgid)) return ignored(MasterIgnored::duplicate);
    if (cfg_.election) {
      if (m.sender == el_.self) return ignored(MasterIgnored::own_broadcast);
      if (MasterElection::Ruled(m.type)) {
        const Action a = el_.Choose(m);
        if (a == Action::Ignore) return ignored(MasterIgnored::not_enabled);
        el_.Run(a, m, from, *this, reg_);
        return taken(a);  // after HandleVote, BecomeMaster is a step of its own (take)
      }
      if (m.type == MsgType::RELAY_ROUTE) {
        if (!MasterRouteOk(m)) return ignored(MasterIgnored::not_enabled);
        MasterRoute(m, from);
        return taken(Action::MasterRoute);
      }
      if (m.type == MsgType::RELAY) {
        // A relayed agent's datagram, forwarded unchanged inside RELAY(master, datagram).
        const auto target = m.param_u16(0);
        if (via != 0 || el_.role != MasterRole::master || !target || *target != el_.self ||
            !decode(m.param(1), inner_).ok() || inner_.type == MsgType::RELAY)
          return ignored(MasterIgnored::not_enabled);
        const Message inner = inner_;
        return Dispatch(inner, from, m.sender);
      }
      if (el_.role != MasterRole::master) return ignored(MasterIgnored::not_master);
      if (Handler(m) == Action::PCTake) return TakeReport(m, from);  // Reports.tla: no registry change
      // The route moves only with a datagram a MasterLogic handler takes (MasterElectionTrace's
      // Route): one the master has no handler for (a peer's RELAY_REQ broadcast) leaves it.
      if (Handler(m) == Action::Ignore) return ignored(MasterIgnored::unexpected_type);
      note_route(m, from, via);
    }
    switch (Handler(m)) {
      case Action::MasterSync:
        if (!MasterSyncOk(m.sender)) return taken(Action::MasterSync, MasterIgnored::ids_exhausted);
        MasterSync(m, from);
        return taken(Action::MasterSync);
      case Action::MasterAnswer: {
        if (!MasterAnswerOk(m)) return taken(Action::MasterAnswer, MasterIgnored::unknown_sender);
        const RegistryEntry& e = *reg_.find(m.sender);
        const bool was_pending = e.pending;
        const std::uint32_t mid = e.mid;
        MasterAnswer(m);  // an answer to nothing pending leaves the pending datagram as it was
        const bool answered = e.pending != was_pending || e.mid != mid;
        return taken(Action::MasterAnswer, answered ? MasterIgnored::none : MasterIgnored::stale_answer);
      }
      case Action::MasterPing:
        if (!MasterPingOk(m)) return taken(Action::MasterPing, MasterIgnored::unknown_sender);
        MasterPing(m, from);
        return taken(Action::MasterPing);
      case Action::MasterReport: {
        const MasterIgnored why = reg_.contains(m.sender) ? MasterIgnored::none : MasterIgnored::unknown_sender;
        if (!MasterReportOk(m)) return taken(Action::MasterReport, MasterIgnored::duplicate);
        MasterReport(m);
        return taken(Action::MasterReport, why);
      }
      case Action::PCTake: return TakeReport(m, from);
      default: return ignored(MasterIgnored::unexpected_type);
    }
  }

  /// Spec Handler(m) for a datagram addressed to the master: the MasterLogic action that takes it,
  /// or Ignore (a type the master has no handler for).
  static Action Handler(const Message& m) noexcept {
    switch (m.type) {
      case MsgType::AGENT:
      case MsgType::PANIC: return Action::MasterSync;
      case MsgType::ACK:
      case MsgType::NOT: return Action::MasterAnswer;
      case MsgType::PING: return Action::MasterPing;
      case MsgType::ACTION_OK:
      case MsgType::ACTION_INTERR:
      case MsgType::ACTION_ERR:
      case MsgType::SENSOR_VALUE:
      case MsgType::EVENT: return Action::MasterReport;
      case MsgType::REPORT:
      case MsgType::REPORT_DROPPED: return Action::PCTake;
      default: return Action::Ignore;
    }
  }

  // ------------------------------------------------ MasterLogic.tla

  /// MasterSync has an entry to act on: one the sender is known by, or an id to give it.
  bool MasterSyncOk(std::uint16_t s) const {
    return !reg_.known(s).empty() || is_assigned_id(s) || next_id_ <= kLastAssignedId;
  }
  /// Spec MasterSync: AGENT or PANIC from announced id s. A registered agent is heard (a synced one
  /// only from its own id) and gets its pending datagram again; a PANIC from a synced entry's own id with a msgid above every msgid
  /// heard from it re-syncs it (new MASTER naming that id, queue kept). A new one gets an id (its
  /// own if s is an assignable id, else the next) and MASTER; an entry with the same peer is replaced.
  /// An adopted id raises next_id past it (max(next_id, s + 1)): no later agent gets an id in use.
  void MasterSync(const Message& m, Peer from) {
    const std::uint16_t s = m.sender;
    const std::vector<std::uint16_t> k = reg_.known(s);  // spec Known(reg, s)
    if (!k.empty()) {
      for (std::uint16_t id : k) {
        RegistryEntry& e = *reg_.find(id);
        // A synced entry is heard only from its own id: AGENT / PANIC from the temporary id it
        // announced is a late copy, or the agent restarted and drew that id again -- kept alive by
        // it, the entry would never be dropped and the agent would stay in PANIC (TLC
        // fleet_agent_restart, BUG HeardByTemp); unheard, it is dropped and the agent registers anew.
        if (!e.synced || s == e.id) e.heard = now_;
        if (m.type == MsgType::PANIC && e.synced && s == e.id && msgid_newer(m.msgid, e.last_msgid)) {
          // The agent lost us while we still hold it (its PONGs were lost): sync it again, a new
          // MASTER; its queued commands follow once it ACKs, reconcile restores its desired state.
          set_synced(e, false);
          reg_.set_ann(e, s);  // MASTER names the id the agent holds now
          e.pending = true;
          e.mid = msgid_++;
          e.sent_at = now_;
          e.resends = 0;
        }
        if (msgid_newer(m.msgid, e.last_msgid)) e.last_msgid = m.msgid;
        send_pending(e);
        rearm(e);
      }
      return;
    }
    std::uint16_t nid = s;
    if (!is_assigned_id(s)) {
      nid = next_id_++;
    } else if (next_id_ <= s) {
      next_id_ = static_cast<std::uint16_t>(s + 1);  // adopted: never hand s out again
    }
    // Entries at the same peer, by id (an index lookup, not a walk).
    for (std::uint16_t id; (id = reg_.first_at(from)) != 0;) {
      fail_queue(*reg_.find(id));
      erase(id);
    }
    RegistryEntry e;
    e.ann = s;
    e.id = nid;
    e.peer = from;
    if (m.type == MsgType::AGENT) {
      e.model = std::string(m.param(0));
      for (std::size_t i = 1; i < m.param_count(); ++i) e.devices.emplace_back(m.param(i));
    }
    e.heard = now_;
    e.last_msgid = m.msgid;
    e.pending = true;
    e.mid = msgid_++;
    e.sent_at = now_;
    erase(nid);
    send_pending(insert(std::move(e)));
  }

  /// MasterAnswer has an entry to act on: the sender is registered.
  bool MasterAnswerOk(const Message& m) const { return reg_.contains(m.sender); }
  /// Spec MasterAnswer: ACK or NOT of the pending msgid moves the agent to its next command. A NOT
  /// makes the desired state unknown (no reconcile) unless a command still queued sets it.
  void MasterAnswer(const Message& m) {
    RegistryEntry& e = *reg_.find(m.sender);
    if (msgid_newer(m.msgid, e.last_msgid)) e.last_msgid = m.msgid;
    const auto ref = m.param_u32(0);
    if (!e.pending || !ref || *ref != e.mid) return;
    e.heard = now_;
    rearm(e);
    const bool ack = m.type == MsgType::ACK;
    if (!e.synced && !ack) return;  // an agent never refuses MASTER; a NOT is no answer to it
    e.pending = false;
    if (!e.synced) {
      set_synced(e, true);
      push(OperatorEvent::Kind::registered, e.id, MsgType::MASTER, std::to_string(e.ann));
    } else if (!e.queue.empty()) {
      Command c = std::move(e.queue.front());
      e.queue.erase(e.queue.begin());
      if (ack) {
        if (c.type == MsgType::BEHAVIOUR) {
          e.behaviour = c.name;
          e.behaviour_args = c.args;
        }
        push(OperatorEvent::Kind::acked, e.id, c.type, {}, c.tag);
      } else {
        push(OperatorEvent::Kind::refused, e.id, c.type, std::string(m.param(1)), c.tag);
        // Do not insist on a state the robot cannot reach (spec PermanentRefusal: every reason but
        // the transient ones, "wrong state" and "no behaviour", which leave the desired state for
        // reconcile; a robot's check on receipt refuses in its own words).
        const std::string_view why = m.param(1);
        if (why != to_string(Refusal::wrong_state) && why != to_string(Refusal::no_behaviour))
          e.desired_known = false;
      }
    }
    start_next(e);
    rearm(e);
  }

  /// MasterPing has an entry to act on: the sender is registered (others get no PONG).
  bool MasterPingOk(const Message& m) const { return reg_.contains(m.sender); }
  /// Spec MasterPing: PONG at once to a registered agent (which is heard) if it is synced. An entry
  /// whose MASTER is unanswered gets none: the agent holds itself synced elsewhere (a late PANIC of
  /// its earlier life registered it here after a crash) and ignores MASTER while synced; PONGs would
  /// keep it from ever panicking and taking the pending MASTER (TLC fleet_late, BUG PongUnsynced).
  /// Reconcile: a synced agent with nothing pending or queued whose reported state is not the
  /// desired one gets the commands that restore it (Restore), after the PONG. Only a fresh PING
  /// (msgid newer than every msgid heard from the agent) reconciles: a stale one, sent before the agent's
  /// last answer, reports a state it has left.
  void MasterPing(const Message& m, Peer from) {
    RegistryEntry& e = *reg_.find(m.sender);
    e.heard = now_;
    const bool fresh = msgid_newer(m.msgid, e.last_msgid);
    if (fresh) e.last_msgid = m.msgid;
    const auto st = m.param_state(0);
    if (st && fresh && (!e.has_state || *st != e.state)) {  // a stale PING's state is old news
      e.state = *st;
      e.has_state = true;
      push(OperatorEvent::Kind::state, e.id, MsgType::PING, std::string(to_string(*st)));
    }
    char num[10];
    const std::string_view p[1] = {decimal(m.msgid, num)};
    if (e.synced) send(from, e.id, MsgType::PONG, p, 1);
    if (st && fresh && e.synced && !e.pending && e.queue.empty() && e.desired_known) {
      Restore(*st, e);
      start_next(e);
    }
    rearm(e);
  }

  /// Spec Restore(st, desired, beh): queues the commands that bring an agent reporting @p st back
  /// to its desired state. PAUSED but WORKING wanted: RESUME (a lost heartbeat paused it); ACTIVE
  /// but WORKING wanted with a behaviour acked: BEHAVIOUR, START (a resync unloaded it); WORKING
  /// but PAUSED wanted: PAUSE; WORKING or PAUSED but ACTIVE wanted: STOP; otherwise nothing.
  static void Restore(AgentState st, RegistryEntry& e) {
    const AgentState d = e.desired;
    if (d == AgentState::WORKING && st == AgentState::PAUSED) {
      e.queue.push_back(Command::simple(MsgType::RESUME));
    } else if (d == AgentState::WORKING && st == AgentState::ACTIVE && !e.behaviour.empty()) {
      e.queue.push_back(Command::assign(e.behaviour, e.behaviour_args));
      e.queue.push_back(Command::simple(MsgType::START));
    } else if (d == AgentState::PAUSED && st == AgentState::WORKING) {
      e.queue.push_back(Command::simple(MsgType::PAUSE));
    } else if (d == AgentState::ACTIVE && (st == AgentState::WORKING || st == AgentState::PAUSED)) {
      e.queue.push_back(Command::simple(MsgType::STOP));
    }
  }

  /// MasterReport has something for the operator: not a copy of a report already passed on.
  bool MasterReportOk(const Message& m) const { return !reports_.contains(m.sender, m.msgid); }
  /// Reports are consumed (Fleet.tla); the operator sees each once (copies are deduplicated).
  void MasterReport(const Message& m) {
    reports_.insert(m.sender, m.msgid, NoPayload{});
    push(OperatorEvent::Kind::report, m.sender, m.type, report_text(m));
  }

  // ------------------------------------------------ Reports.tla

  /// REPORT / REPORT_DROPPED: PCTake, then PCAck in the same step. Reports.tla's actions touch
  /// none of MasterLogic's or Election's variables (REPORT_ACK draws no msgid: it is cumulative
  /// and idempotent, no receiver tells it from its copies).
  MasterReceipt TakeReport(const Message& m, Peer from) {
    // Only a registered agent's: a record (and the ids a restarted PC keeps from it) is never
    // opened by a stranger's datagram; an agent a restarted PC does not know yet syncs again and
    // then sends it everything it holds.
    if (!reg_.contains(m.sender)) return ignored(MasterIgnored::unknown_sender);
    if (!PCTakeOk(m)) return ignored(MasterIgnored::bad_report);
    rec_traced_ = m.sender;
    rec_before_ = records_[m.sender].stored();
    PCTake(m);
    PCAck(m.sender, from);
    return taken(Action::PCTake);
  }

  /// PCTake has a number to offer: REPORT(seq, first, datagram) with a report of the sender
  /// inside, or REPORT_DROPPED(first, last); numbers valid (reports.hpp: 1..4294967294, an agent's
  /// last). Bad: ignored as bad_report.
  bool PCTakeOk(const Message& m) {
    const auto a = m.param_u32(0), b = m.param_u32(1);
    if (!a || !b || *a == 0xFFFFFFFFu || *b == 0xFFFFFFFFu) return false;
    if (m.type == MsgType::REPORT_DROPPED) return *a != 0 && *a <= *b;
    return *a != 0 && *b != 0 && *b <= *a && decode(m.param(2), report_).ok() && report_.sender == m.sender &&
           is_report(report_.type);
  }
  /// Spec PCTake: the number is recorded if it is the next of the sender's record (reports.hpp
  /// PCTake); a report recorded goes to the operator numbered, a marker as reports_dropped,
  /// numbers the agent no longer held as reports_skipped; each into the record (keep_record).
  void PCTake(const Message& m) {
    const bool marker = m.type == MsgType::REPORT_DROPPED;
    const std::uint32_t seq = *m.param_u32(0), first = marker ? seq : *m.param_u32(1);
    const std::uint32_t last = marker ? *m.param_u32(1) : 0;
    ReportRecord& r = records_[m.sender];
    const ReportRecord before = r;
    std::uint32_t skipped = 0;
    ev3proto::PCTake(r, seq, last, first, skipped);
    const ReportEntries e = taken_entries(before, r);
    record_events(m.sender, e, report_.type, e.report != 0 ? report_text(report_) : std::string(),
                  [this](OperatorEvent&& ev) { note_record(std::move(ev)); });
  }
  /// Spec PCAck: REPORT_ACK(the last number recorded) to the sender, cumulative, with msgid 0.
  void PCAck(std::uint16_t agent, Peer from) {
    const ReportRecord& r = records_[agent];
    if (r.stored() == 0) return;
    char num[10];
    const std::string_view p[1] = {decimal(r.stored(), num)};
    send_with(from, agent, 0, MsgType::REPORT_ACK, p, 1);
  }
  /// An entry of the record: an operator event, kept for ready()'s append (keep_record).
  void note_record(OperatorEvent&& e) {
    if (cfg_.keep_record) record_.push_back(e);
    ev_.push_back(std::move(e));
  }
  /// A report's params joined by ':' (OperatorEvent::text).
  static std::string report_text(const Message& m) {
    std::string text;
    for (std::size_t i = 0; i < m.param_count(); ++i) {
      if (i) text += ':';
      text += std::string(m.param(i));
    }
    return text;
  }

  /// MasterCommand has an entry to act on: @p agent is registered, or 0 (all).
  bool MasterCommandOk(std::uint16_t agent) const {
    return agent == kBroadcastId || reg_.contains(agent);
  }
  /// Spec MasterCommand: the operator's command for agent @p agent (0 = all: not in the spec),
  /// the agents it is queued for appended to @p to.
  void MasterCommand(std::uint16_t agent, const Command& c, std::vector<std::uint16_t>& to) {
    if (agent != kBroadcastId) {
      enqueue(*reg_.find(agent), c);
      to.push_back(agent);
      return;
    }
    for (auto& kv : reg_) {  // in id order
      enqueue(kv.second, c);
      to.push_back(kv.first);
    }
  }

  /// MasterTick is due at @p now: as MASTER, an entry's resend or drop time has come.
  bool MasterTickOk(Millis now) const noexcept {
    return el_.role == MasterRole::master && entries_due() <= now;
  }
  /// Spec MasterTick at now_: drop agents quiet for the drop timeout, resend due pending datagrams
  /// (an operator command fails after max_resends resends; MASTER is resent until ACK or drop and
  /// its resends are not counted).
  /// Only the entries due (their deadline <= now_) are visited, in order of id: the others would
  /// be left as they are by the spec's walk of every entry.
  void MasterTick() {
    due_.clear();
    for (std::uint16_t id; drops_.pop_due(now_, id);) due_.push_back(id);
    for (std::uint16_t id; resends_.pop_due(now_, id);) due_.push_back(id);
    std::sort(due_.begin(), due_.end());
    due_.erase(std::unique(due_.begin(), due_.end()), due_.end());
    for (std::uint16_t id : due_) {
      RegistryEntry& e = *reg_.find(id);
      if (now_ - e.heard >= cfg_.timers[Timer::drop]) {
        fail_queue(e);
        push(OperatorEvent::Kind::dropped, e.id, MsgType::PING, {});
        erase(id);
        el_.DropMember(id);
        continue;
      }
      if (e.pending && now_ - e.sent_at >= cfg_.timers[Timer::resend]) {
        if (e.synced && e.resends >= cfg_.max_resends) {
          push(OperatorEvent::Kind::timed_out, e.id, e.queue.front().type, {}, e.queue.front().tag);
          e.queue.erase(e.queue.begin());
          e.pending = false;
          start_next(e);
        } else {
          if (e.synced) ++e.resends;
          e.sent_at = now_;
          send_pending(e);
        }
      }
      rearm(e);
    }
  }

  // ------------------------------------------------ relay routes

  /// RELAY_ROUTE of our epoch to us (MASTER) for an agent registered or a member.
  bool MasterRouteOk(const Message& m) const {
    const auto e = m.param_u32(0);
    const auto a = m.param_u16(1);
    return el_.role == MasterRole::master && m.receiver == el_.self && e && *e == el_.epoch && a &&
           (reg_.contains(*a) || el_.known(*a));
  }
  /// RELAY_ROUTE(epoch, agent) from relay p (Election abstracts it: the master reads the table):
  /// the agent is reached through p from now on (a member not registered yet is adopted).
  void MasterRoute(const Message& m, Peer from) {
    const std::uint16_t a = *m.param_u16(1);
    RegistryEntry* e = reg_.find(a);
    if (e == nullptr) e = &adopt(a, from);
    e->via = m.sender;
    reg_.set_peer(*e, from);
  }

  /// Where a registered agent is (direct, or through relay @p via); a member we do not hold yet
  /// (it follows our LEADER) is registered as synced when it pings.
  void note_route(const Message& m, Peer from, std::uint16_t via) {
    RegistryEntry* found = reg_.find(m.sender);
    if (found == nullptr) {
      if (m.type != MsgType::PING || !el_.known(m.sender)) return;
      found = &adopt(m.sender, from);
    }
    RegistryEntry& e = *found;
    if (m.type == MsgType::PING && !e.synced && el_.known(m.sender)) {
      // A member we were syncing (its PANIC reached us) pings: it follows our LEADER already.
      set_synced(e, true);
      e.pending = false;
      start_next(e);
      rearm(e);
    }
    // A relay forwards the agent's datagrams unchanged: from the relay's peer they are relayed.
    if (via == 0 && e.via != 0 && from == e.peer) return;
    reg_.set_peer(e, from);
    e.via = via;
  }
  RegistryEntry& adopt(std::uint16_t id, Peer from) {
    // As MasterSync for an assigned id: never hand this id out again (IdsInv; fuzz_master found
    // a member adopted on its PING below next_id, which a new agent would then have been given).
    if (is_assigned_id(id) && next_id_ <= id) next_id_ = static_cast<std::uint16_t>(id + 1);
    RegistryEntry e;
    e.ann = id;
    e.id = id;
    e.peer = from;
    e.synced = true;
    e.desired_known = false;  // what the fleet's earlier master wanted is not known here
    e.heard = now_;
    return insert(std::move(e));
  }

  void broadcast(MsgType t, const std::vector<std::string>& params) {
    std::vector<std::string_view> p(params.begin(), params.end());
    char buf[kMaxDatagram];
    const EncodeResult r = encode_parts(el_.self, kBroadcastId, msgid_++, static_cast<std::uint8_t>(t),
                                        p.data(), p.size(), buf, sizeof buf);
    if (r.ok()) tx_.push_back(MasterTransmit{0, Dest::broadcast, std::string(buf, r.size)});
  }
  void send(Peer to, std::uint16_t id, MsgType t, const std::vector<std::string>& params) {
    std::vector<std::string_view> p(params.begin(), params.end());
    send(to, id, t, p.data(), p.size());
  }

  // ------------------------------------------------ registry (indexes and deadlines)

  /// The earliest deadline of an entry: a drop or a resend.
  Millis entries_due() const noexcept {
    const Millis d = drops_.next(), r = resends_.next();
    return r < d ? r : d;
  }
  /// After heard, pending or sent_at of @p e changed: its drop time is heard + drop, its resend
  /// time (while a datagram is pending) sent_at + resend.
  void rearm(const RegistryEntry& e) {
    drops_.refresh(e.id, e.heard);
    if (e.pending)
      resends_.refresh(e.id, e.sent_at);
    else
      resends_.remove(e.id);
  }

  /// Adds @p e (its id not registered) to the registry and its deadline.
  RegistryEntry& insert(RegistryEntry e) {
    RegistryEntry& r = reg_.insert(std::move(e));
    rearm(r);
    if (r.synced) {
      el_.Synced(r.id);  // back: wanted again
      ++el_.members_rev;
    }
    return r;
  }
  /// Removes entry @p id from the registry and its deadline.
  void erase(std::uint16_t id) {
    const RegistryEntry* e = reg_.find(id);
    if (e == nullptr) return;
    if (e->synced) ++el_.members_rev;
    drops_.remove(id);
    resends_.remove(id);
    reg_.erase(id);
  }
  void set_synced(RegistryEntry& e, bool synced) {
    if (e.synced != synced) ++el_.members_rev;
    if (synced) el_.Synced(e.id);  // back: wanted again
    e.synced = synced;
  }

  void enqueue(RegistryEntry& e, const Command& c) {
    e.queue.push_back(c);
    if (sets_desired(c.type)) {
      e.desired = desired_after(c.type, e.desired);
      e.desired_known = true;
    }
    if (e.synced && !e.pending) start_next(e);
    rearm(e);
  }

  /// Sends the next queued command, if any, with a new msgid.
  void start_next(RegistryEntry& e) {
    if (e.queue.empty()) return;
    e.pending = true;
    e.mid = msgid_++;
    e.sent_at = now_;
    e.resends = 0;
    send_pending(e);
  }

  /// Spec Pending(r): the datagram of the pending command (same msgid every time).
  void send_pending(const RegistryEntry& e) {
    if (!e.pending) return;
    if (!e.synced) {
      char num[10];
      const std::string_view p[1] = {decimal(e.ann, num)};
      send_with(e.peer, e.id, e.mid, MsgType::MASTER, p, 1);
      return;
    }
    const Command& c = e.queue.front();
    std::vector<std::string_view> p;
    if (c.type == MsgType::BEHAVIOUR) {
      p.push_back(c.name);
      for (const auto& a : c.args) p.push_back(a);
    }
    send_with(e.peer, e.id, e.mid, c.type, p.data(), p.size());
  }

  void fail_queue(RegistryEntry& e) {
    if (!e.synced) return;
    for (const Command& c : e.queue) push(OperatorEvent::Kind::timed_out, e.id, c.type, {}, c.tag);
    e.queue.clear();
    e.pending = false;
  }

  void send(Peer to, std::uint16_t id, MsgType t, const std::string_view* p, std::size_t n) {
    send_with(to, id, msgid_++, t, p, n);
  }
  void send_with(Peer to, std::uint16_t id, std::uint32_t mid, MsgType t, const std::string_view* p,
                 std::size_t n) {
    char buf[kMaxDatagram];
    const EncodeResult r = encode_parts(el_.self, id, mid, static_cast<std::uint8_t>(t), p, n, buf,
                                        sizeof buf);
    if (!r.ok()) return;
    std::string bytes(buf, r.size);
    if (cfg_.election) {
      // Fencing: an elected master's (epoch > 1) MASTER and commands travel in EPOCH_CMD.
      if (el_.epoch > 1 && (t == MsgType::MASTER || is_command(t)))
        bytes = wrap(id, mid, MsgType::EPOCH_CMD, el_.epoch, bytes);
      // Relay: an agent behind a relay gets RELAY(agent, datagram) through it.
      const RegistryEntry* e = reg_.find(id);
      if (e != nullptr && e->via != 0) bytes = wrap(e->via, mid, MsgType::RELAY, id, bytes);
    }
    if (!bytes.empty()) tx_.push_back(MasterTransmit{to, Dest::peer, std::move(bytes)});
  }
  std::string wrap(std::uint16_t to, std::uint32_t mid, MsgType t, std::uint32_t first, const std::string& inner) {
    char buf[kMaxDatagram];
    const EncodeResult r = encode_envelope(el_.self, to, mid, t, first, inner, buf, sizeof buf);
    return r.ok() ? std::string(buf, r.size) : std::string();
  }

  void push(OperatorEvent::Kind k, std::uint16_t agent, MsgType t, std::string text, std::uint32_t tag = 0) {
    OperatorEvent e{k, agent, t, std::move(text)};
    e.tag = tag;
    ev_.push_back(std::move(e));
  }

  // ------------------------------------------------------------------ trace

  struct Snapshot {
    std::string reg;
    std::uint16_t next_id = 0;
    std::uint32_t msgid = 0;
    std::string_view life;
    std::uint32_t epoch = 0;
    std::string votes;
    std::string members;
    std::uint32_t mepoch = 0;
  };
  static std::string ids_json(const std::set<std::uint16_t>& ids) {
    std::string v = "[";
    for (std::uint16_t id : ids) v += (v.size() > 1 ? "," : "") + std::to_string(id);
    return v + "]";
  }
  std::string votes_json() const { return ids_json(el_.votes); }

  /// The registry as the spec's ms.reg (JSON array of MasterLogic entries, by id), for trace
  /// records: ann, id, ep, synced, pending, mid, resends, queue ([{type, name}], name "NONE" but
  /// for BEHAVIOUR), desired, beh ("NONE"), quiet (now - heard, ms), hi.
  std::string reg_json() const {
    std::string s = "[";
    for (const auto& kv : reg_.map()) {
      const RegistryEntry& e = kv.second;
      if (s.size() > 1) s += ',';
      s += "{\"ann\":" + std::to_string(e.ann) + ",\"id\":" + std::to_string(e.id) +
           ",\"ep\":" + std::to_string(e.peer) + ",\"synced\":" + (e.synced ? "true" : "false") +
           ",\"pending\":" + (e.pending ? "true" : "false") + ",\"mid\":" + std::to_string(e.mid) +
           ",\"resends\":" + std::to_string(e.resends) + ",\"queue\":[";
      bool first = true;
      for (const Command& c : e.queue) {
        if (!first) s += ',';
        first = false;
        s += "{\"type\":\"" + std::string(to_string(c.type)) + "\",\"name\":";
        json_string(s, c.type == MsgType::BEHAVIOUR ? std::string_view(c.name) : std::string_view("NONE"));
        s += '}';
      }
      s += "],\"desired\":\"" +
           std::string(e.desired_known ? to_string(e.desired) : std::string_view("UNKNOWN")) +
           "\",\"beh\":";
      json_string(s, e.behaviour.empty() ? std::string_view("NONE") : std::string_view(e.behaviour));
      s += ",\"quiet\":" + std::to_string(now_ - e.heard) + ",\"hi\":" + std::to_string(e.last_msgid) + "}";
    }
    return s + "]";
  }

  Snapshot snap() const {
    if constexpr (Trace::enabled) {
      if (trace_ != nullptr)
        return Snapshot{reg_json(),  next_id_, msgid_, to_string(el_.role), el_.epoch, votes_json(),
                        ids_json(el_.members), el_.mepoch};
    }
    return Snapshot{};
  }

  void record(Action a, Snapshot& before, std::string_view msg) {
    if constexpr (Trace::enabled) {
      if (trace_ == nullptr) return;
      MasterTraceRecord r;
      r.action = a;
      r.msg = msg;
      r.now = now_;
      r.reg_before = std::move(before.reg);
      r.reg_after = reg_json();
      r.next_id_before = before.next_id;
      r.next_id_after = next_id_;
      r.msgid_before = before.msgid;
      r.msgid_after = msgid_;
      r.life_before = before.life;
      r.life_after = to_string(el_.role);
      r.epoch_before = before.epoch;
      r.epoch_after = el_.epoch;
      r.votes_before = std::move(before.votes);
      r.votes_after = votes_json();
      r.members_before = std::move(before.members);
      r.members_after = ids_json(el_.members);
      r.mepoch_before = before.mepoch;
      r.mepoch_after = el_.mepoch;
      if (a == Action::PCTake) {
        r.rec_agent = rec_traced_;
        r.rec_before = rec_before_;
        r.rec_after = records_[rec_traced_].stored();
      }
      trace_->record(r);
    } else {
      (void)a, (void)before, (void)msg;
    }
  }

  MasterConfig cfg_;
  Trace* trace_ = nullptr;
  std::uint16_t next_id_;
  std::uint32_t msgid_;
  Millis now_;
  Registry reg_;
  DeadlineList<std::uint16_t> drops_;      // entries by heard: heard + drop
  DeadlineList<std::uint16_t> resends_;    // pending entries by sent_at: sent_at + resend
  std::vector<std::uint16_t> due_;         // MasterTick's scratch
  CopyWindow copies_;                      // MasterConfig::drop_copies
  DedupeWindow<256> reports_;
  std::deque<MasterTransmit> tx_;
  std::deque<OperatorEvent> ev_;
  std::map<std::uint16_t, ReportRecord> records_;  // Reports.tla rec / nx, per agent
  std::vector<OperatorEvent> record_;              // the record's entries not yet appended (keep_record)
  Message report_;                                 // the report inside the REPORT PCTake takes
  std::uint16_t rec_traced_ = 0;                   // PCTake's sender and its last number recorded
  std::uint32_t rec_before_ = 0;                   // ... as the step started (its trace record)
  std::uint32_t rejected_ = 0;
  Message rx_;
  MasterElection el_;  // Election.tla's variables of the master node, its rules (election/master.hpp)
  Message inner_;
  // ready(): what was written last.
  bool written_ = false;
  std::uint16_t written_id_ = 0;
  std::uint32_t written_epoch_ = 0, written_mepoch_ = 0;
  std::vector<std::uint16_t> written_members_;
  std::uint64_t written_rev_ = 0;  // el_.members_rev when the membership was last compared
  MsgidReservation reserved_;

  /// True when ready() must write before sending: the first time, or next_id, the epoch or the
  /// membership published differ from what was written, or the msgid block runs low.
  bool durable_due() {
    if (!written_ || next_id_ != written_id_ || el_.epoch != written_epoch_ || reserved_.low(msgid_)) return true;
    if (el_.members_rev == written_rev_) return false;  // no walk per datagram
    const MasterDurable d = durable();
    const bool same = d.members_epoch == written_mepoch_ &&
                      std::equal(d.members, d.members + d.member_count, written_members_.begin(), written_members_.end());
    if (same) written_rev_ = el_.members_rev;
    return !same;
  }
};

}  // namespace ev3proto
