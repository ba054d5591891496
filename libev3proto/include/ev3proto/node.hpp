/// @file node.hpp
/// @brief One robot node: the agent core, the Master core it runs while it is the elected master of
///        an epoch, and the copy-dedupe window in front of that Master core.
///
/// The same sans-I/O shape as the cores: datagrams, time, device events and operator commands in;
/// datagrams, events and the next deadline out. Every datagram is decoded once (the agent core gets
/// the decoded Message). After every input the node compares what the agent core reports with
/// what it reported last (the durable state by its revision, Agent::durable_rev()) and emits an
/// event for each change, as etcd raft's Ready carries HardState
/// and SoftState only when they changed: `durable` (epoch, votedFor and the membership known),
/// `role`, `leader` (leader, following, via), `relays`, and `master_started` / `master_stopped` for
/// the Master core. ready(write, send) hands the program the durable state to write, then the
/// datagrams, in that order (raft's Ready). docs/core.md "The node".
///
/// Memory: the agent core and the window are inline (no heap). The Master core allocates (its
/// registry is a std::map): a node allocates only while it runs one, i.e. after winning an epoch.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "agent.hpp"
#include "dedupe.hpp"
#include "master.hpp"
#include "ring.hpp"

namespace ev3proto {

/// What a node did with one datagram.
struct NodeHandled {
  Handled agent;                  ///< The agent core's action, or why it took none (undecodable...).
  Action master = Action::Ignore; ///< The Master core's action (Ignore: none running, not its, or a copy).
  bool copy = false;              ///< A copy the window kept from the Master core (its first copy went in).
  /// Why nothing took the datagram: Ignored::no when the agent core did, for_the_master_core when
  /// only the Master core did, else the agent core's reason.
  Ignored why() const noexcept {
    if (agent.taken()) return Ignored::no;
    if (master != Action::Ignore) return Ignored::for_the_master_core;
    return agent.why;
  }
};

/// A datagram a node wants sent.
struct NodeTransmit {
  Dest dest = Dest::broadcast;   ///< master (the agent's master), broadcast, or peer.
  Peer peer = 0;                 ///< Dest::master: the master's handle (0 if unknown); Dest::peer: the receiver's.
  std::string_view bytes;        ///< The datagram; valid until the next call into the node.
  bool from_master_core = false; ///< Sent by the Master core (the agent's id, msgids from elected_master_first_msgid(epoch) on).
};

/// An event for the robot program: the agent core's (state, LED, behaviour control) and the node's
/// own, reported once per change.
struct NodeEvent {
  /// Which fields are meaningful.
  enum class Kind : std::uint8_t {
    state,          ///< The agent's state changed (@c state).
    led,            ///< The LED pattern changed (@c led).
    control,        ///< The behaviour runner must act (@c control; start/restart run agent().behaviour()).
    durable,        ///< Epoch, vote or membership changed (@c durable, was @c previous): persist before sending.
    role,           ///< The election role changed (@c role; master: it won @c epoch).
    leader,         ///< The master followed changed (@c leader in epoch @c epoch, through @c via; 0 = none).
    relays,         ///< The agents this node relays for changed (agent().election().relays.id(i)).
    master_started, ///< A Master core runs: this node is master of @c epoch (agent().election().members[i]: its fleet).
    master_stopped, ///< The Master core of @c epoch stepped down (a newer epoch) and was dropped.
  } kind = Kind::state;
  State state = State::IDLE;               ///< state
  Led led = Led::YELLOW_BLINK;             ///< led
  ControlKind control = ControlKind::stop; ///< control
  Durable durable;                         ///< durable: the new epoch, vote and membership
  Durable previous;                        ///< durable: the one before
  ElectionRole role = ElectionRole::none;                  ///< role
  std::uint16_t leader = 0;                ///< leader
  std::uint16_t via = 0;                   ///< leader
  std::uint32_t epoch = 0;                 ///< role (master), leader (following), master_started / _stopped
  bool handed_over = false;                ///< master_stopped: HANDOVER was sent to the new master
  std::uint32_t rev = 0;                   ///< durable: the agent core's durable_rev() it is of
};

/// Spelling of a node event kind ("master_started").
constexpr std::string_view to_string(NodeEvent::Kind k) noexcept {
  switch (k) {
    case NodeEvent::Kind::state: return "state";
    case NodeEvent::Kind::led: return "led";
    case NodeEvent::Kind::control: return "control";
    case NodeEvent::Kind::durable: return "durable";
    case NodeEvent::Kind::role: return "role";
    case NodeEvent::Kind::leader: return "leader";
    case NodeEvent::Kind::relays: return "relays";
    case NodeEvent::Kind::master_started: return "master_started";
    case NodeEvent::Kind::master_stopped: return "master_stopped";
  }
  return {};
}

/// One robot node.
/// @tparam AgentTrace the agent core's trace sink (agent.hpp).
/// @tparam MasterTrace the Master core's trace sink (master.hpp); each Master core gets the sink
///         master_trace(id, epoch) returns (NodeConfig).
/// @tparam CopySlots (sender, msgid) pairs the window in front of the Master core remembers.
template <typename AgentTrace = NoTrace, typename MasterTrace = NoTrace, std::size_t CopySlots = 4096>
class Node {
 public:
  /// The agent core.
  using AgentCore = Agent<AgentTrace>;
  /// The Master core run while elected.
  using MasterCore = Master<MasterTrace>;
  /// "No deadline".
  static constexpr Millis kNever = ~Millis{0};

  /// Construction parameters.
  struct Config {
    AgentConfig agent;  ///< The agent core's (its timers serve the Master core too).
    /// The trace sink for the Master core this node runs as master of @p epoch with id @p id
    /// (nullptr or unset: none). Called when that core starts; the previous core is gone by then.
    std::function<MasterTrace*(std::uint16_t id, std::uint32_t epoch)> master_trace;
    /// poll_transmit() gives no datagram while a durable change was handed out neither by ready()
    /// nor as a `durable` event. Off only for a harness that drains datagrams from inside the
    /// cores' trace hooks, before the node has seen the change (the multi-node transcripts).
    bool durable_first = true;
  };

  /// A node in IDLE at @p now (the agent core's Init).
  Node(const Config& config, Millis now, AgentTrace* trace = nullptr)
      : cfg_(config), agent_(config.agent, now, trace) {
    seen_durable_ = agent_.durable();
    seen_durable_rev_ = written_rev_ = handed_rev_ = agent_.durable_rev();
  }

  // ---------------------------------------------------------------- inputs

  /// Time moves to @p now in both cores.
  void advance(Millis now) {
    if (master_) master_->advance(now);
    agent_.advance(now);
    report_changes(now);
  }

  /// A datagram from @p from at @p now: decoded once, for both cores; the first copy of each (sender, msgid) goes
  /// to the Master core (when one runs), then the agent core takes it. Returns what each did.
  NodeHandled handle_datagram(std::string_view bytes, Peer from, Millis now) {
    NodeHandled h;
    h.agent.decode = decode(bytes, rx_);
    if (!h.agent.decode.ok()) {
      if (master_) master_->advance(now);
      agent_.advance(now);
      ++rejected_;
      h.agent.why = Ignored::undecodable;
      report_changes(now);
      return h;
    }
    if (master_) {
      if (copies_.first_time(rx_.sender, rx_.msgid)) {
        h.master = master_->handle_message(rx_, bytes, from, now).action;  // decoded once, here
      } else {
        h.copy = true;
      }
    }
    const Action a = h.master;
    h.agent = agent_.handle_message(rx_, bytes, from, now);
    h.master = a;
    report_changes(now);
    return h;
  }

  /// The running action finished (agent core action_ok).
  bool action_ok(Millis now) { return after(agent_.action_ok(now), now); }
  /// A warning the behaviour cannot resolve (agent core action_interrupted).
  bool action_interrupted(Warning w, Millis now) { return after(agent_.action_interrupted(w, now), now); }
  /// The running action failed for @p why (agent core action_failed).
  bool action_failed(std::string_view why, Millis now) { return after(agent_.action_failed(why, now), now); }
  /// A sensor reading (agent core sensor_report).
  bool sensor_report(std::string_view port, std::string_view mode, const std::string_view* values,
                     std::size_t count, Millis now) {
    return after(agent_.sensor_report(port, mode, values, count, now), now);
  }
  /// Device bits unplugged from a port (agent core device_unplugged).
  bool device_unplugged(std::uint32_t device, std::string_view port, Millis now) {
    return after(agent_.device_unplugged(device, port, now), now);
  }
  /// Device bits plugged back on a port (agent core device_plugged).
  bool device_plugged(std::uint32_t device, std::string_view port, Millis now) {
    return after(agent_.device_plugged(device, port, now), now);
  }
  /// A robot event that changes no protocol state (agent core robot_event).
  bool robot_event(RobotEventKind e, std::string_view port, Millis now) {
    return after(agent_.robot_event(e, port, now), now);
  }
  /// The battery is low (agent core battery_low).
  bool battery_low(Millis now) { return after(agent_.battery_low(now), now); }
  /// The program is about to exit: EVENT(LEAVING) to the master when synced (agent core leaving).
  bool leaving(Millis now) { return after(agent_.leaving(now), now); }

  /// An operator command for the fleet this node is master of (agent id, 0 = all; the Master
  /// core's MasterCommand). False (nothing done) unless a Master core runs as master.
  bool command(std::uint16_t agent, const Command& c, Millis now) {
    if (!master_ || master_->role() != MasterRole::master) return false;
    master_->command(agent, c, now);
    report_changes(now);
    return true;
  }

  // ---------------------------------------------------------------- outputs

  /// What the calls since the last ready() left for the program, in the order it must be done (as
  /// etcd raft's Ready): first @p write gets the durable state when it changed since the last write
  /// (`bool write(const Durable&)`: true once it is on stable storage), then @p send gets every
  /// datagram (`void send(const NodeTransmit&)`). When @p write fails, nothing is sent and false is
  /// returned: the datagrams stay queued (the oldest dropped when the queue is full) and the next
  /// ready() writes again first. A program that calls ready() after every input never sends a
  /// datagram whose durable state (a VOTE's votedFor) is not on stable storage.
  template <typename Write, typename Send>
  bool ready(Write&& write, Send&& send) {
    if (!persist(write)) return false;
    NodeTransmit t;
    while (poll_transmit(t)) send(static_cast<const NodeTransmit&>(t));
    return true;
  }

  /// ready()'s first half: @p write gets the durable state when it changed since the last write.
  /// True when nothing was due or the write succeeded. For a program that writes as the `durable`
  /// event comes, so that its log reads in event order; ready() still writes first whatever is due.
  template <typename Write>
  bool persist(Write&& write) {
    if (agent_.durable_rev() == written_rev_) return true;
    if (!write(static_cast<const Durable&>(agent_.durable()))) return false;
    written_rev_ = handed_rev_ = agent_.durable_rev();
    return true;
  }

  /// Takes the next datagram to send: those a Master core dropped had not sent yet (its HANDOVER)
  /// first, then the agent core's, then the running Master core's. None while the durable state
  /// changed and was handed out neither as a `durable` event (poll_event) nor by ready(): the
  /// program has not been told what to write before they go (Config::durable_first). Programs
  /// call ready(); this is the step below it, for drivers that keep the order themselves.
  bool poll_transmit(NodeTransmit& out) {
    if ((cfg_.durable_first && agent_.durable_rev() != handed_rev_) || !next_transmit(out)) return false;
    if (out.peer == 0 && out.dest == Dest::master) ++unrouted_.to_master;
    if (out.peer == 0 && out.dest == Dest::peer) ++unrouted_.to_peer;
    return true;
  }

  /// Takes the next event: the agent core's (in order), then the node's of the same call. Drain
  /// events before datagrams: a `durable` event must be on stable storage before they are sent.
  bool poll_event(NodeEvent& out) {
    AgentEvent e;
    if (agent_.poll_event(e)) {
      out = NodeEvent{};
      out.kind = e.kind == AgentEvent::Kind::state ? NodeEvent::Kind::state
                 : e.kind == AgentEvent::Kind::led ? NodeEvent::Kind::led
                                                   : NodeEvent::Kind::control;
      out.state = e.state;
      out.led = e.led;
      out.control = e.control;
      return true;
    }
    if (!ev_.pop(out)) return false;
    if (out.kind == NodeEvent::Kind::durable) handed_rev_ = out.rev;
    return true;
  }

  /// Takes the Master core's next operator event (registered, acked, report...); false when none.
  bool poll_operator_event(OperatorEvent& out) { return master_ && master_->poll_event(out); }

  /// When advance() must be called next at the latest: the earlier of the two cores' deadlines.
  Millis next_deadline() const noexcept {
    Millis t = agent_.next_deadline();
    if (master_) {
      const Millis m = master_->next_deadline();
      if (m < t) t = m;
    }
    return t;
  }

  // ---------------------------------------------------------------- observers

  /// The agent core (state, id, behaviour, election variables...).
  const AgentCore& agent() const noexcept { return agent_; }
  /// The Master core while one runs (registry, role), else nullptr.
  const MasterCore* master() const noexcept { return master_ ? &*master_ : nullptr; }
  /// Datagrams that did not decode.
  std::uint32_t rejected() const noexcept { return rejected_; }
  /// Datagrams handed out with no peer to send them to (NodeTransmit::peer 0).
  struct Unrouted {
    std::uint32_t to_master = 0; ///< For the master before its address is known: the program broadcasts them.
    std::uint32_t to_peer = 0;   ///< For a peer whose handle is 0: the program drops them.
  };
  /// How many datagrams fell back for want of an address, by kind (Unrouted).
  const Unrouted& unrouted() const noexcept { return unrouted_; }
  /// Events dropped because the caller did not drain them.
  std::uint32_t overflowed() const noexcept { return overflowed_ + agent_.overflowed(); }

 private:
  static constexpr std::size_t kEventSlots = 16;

  /// poll_transmit() without the hold and the counts.
  bool next_transmit(NodeTransmit& out) {
    if (!parting_.empty()) {
      mtx_ = std::move(parting_.front().bytes);
      out = NodeTransmit{parting_.front().dest, parting_.front().peer, mtx_, true};
      parting_.erase(parting_.begin());  // a few at most
      return true;
    }
    Transmit t;
    if (agent_.poll_transmit(t)) {
      out = NodeTransmit{t.dest, t.peer, t.bytes, false};
      return true;
    }
    MasterTransmit mt;
    if (master_ && master_->poll_transmit(mt)) {
      mtx_ = std::move(mt.bytes);
      out = NodeTransmit{mt.dest, mt.peer, mtx_, true};
      return true;
    }
    return false;
  }

  bool after(bool taken, Millis now) {
    report_changes(now);
    return taken;
  }

  /// After every input: start or drop the Master core, then report what changed since last time.
  void report_changes(Millis now) {
    if (agent_.durable_rev() != seen_durable_rev_) {  // the agent core counts its changes: no rebuild per input
      seen_durable_rev_ = agent_.durable_rev();
      NodeEvent e = make(NodeEvent::Kind::durable);
      e.previous = seen_durable_;
      e.rev = seen_durable_rev_;
      push(e);
      seen_durable_ = e.durable;
    }
    const auto& el = agent_.election();
    if (el.role != seen_role_) {
      seen_role_ = el.role;
      NodeEvent e = make(NodeEvent::Kind::role);
      e.role = seen_role_;
      e.epoch = seen_role_ == ElectionRole::master ? el.master_epoch : el.epoch;
      push(e);
    }
    if (el.leader != seen_leader_ || el.following != seen_following_ || el.via != seen_via_) {
      seen_leader_ = el.leader;
      seen_following_ = el.following;
      seen_via_ = el.via;
      NodeEvent e = make(NodeEvent::Kind::leader);
      e.leader = seen_leader_;
      e.epoch = seen_following_;
      e.via = seen_via_;
      push(e);
    }
    if (relays_changed()) push(make(NodeEvent::Kind::relays));
    run_master_core(now);
  }

  /// The Master core runs while the agent core is master of an epoch (a new core per epoch won),
  /// seeded with the agent's membership and msgids disjoint from the agent core's, above those of
  /// every epoch this node won before (msgids.hpp: followers ignore a command below one they
  /// remember from this id, so a restarted node must not start lower); it is dropped
  /// once it stepped down and the agent core is master no more.
  void run_master_core(Millis now) {
    const auto& el = agent_.election();
    if (el.role == ElectionRole::master && (!master_ || master_->epoch() != el.master_epoch)) {
      master_.reset();
      std::vector<std::uint16_t> members;
      for (std::size_t i = 0; i < el.members.size(); ++i) members.push_back(el.members[i]);
      MasterTrace* trace = cfg_.master_trace ? cfg_.master_trace(agent_.id(), el.master_epoch) : nullptr;
      master_.emplace(MasterConfig::for_elected_agent(cfg_.agent.timers, agent_.id(), el.master_epoch,
                                                      std::move(members)),
                      now, trace);
      NodeEvent e = make(NodeEvent::Kind::master_started);
      e.epoch = el.master_epoch;
      push(e);
      master_->advance(now);  // its first LEADER is due now
    }
    if (master_ && master_->role() == MasterRole::stepped_down && el.role != ElectionRole::master) {
      // what it sent as it stepped down (HANDOVER to the new master) still goes out
      MasterTransmit mt;
      while (master_->poll_transmit(mt)) parting_.push_back(std::move(mt));
      NodeEvent e = make(NodeEvent::Kind::master_stopped);
      e.epoch = el.master_epoch;
      e.handed_over = master_->handed_over();
      master_.reset();
      push(e);
    }
  }

  bool relays_changed() {
    const auto& relays = agent_.election().relays;
    bool changed = relays.size() != seen_relay_count_;
    for (std::size_t i = 0; !changed && i < seen_relay_count_; ++i) changed = relays.id(i) != seen_relays_[i];
    if (!changed) return false;
    seen_relay_count_ = relays.size() < kMaxSeenRelays ? relays.size() : kMaxSeenRelays;
    for (std::size_t i = 0; i < seen_relay_count_; ++i) seen_relays_[i] = relays.id(i);
    return true;
  }

  NodeEvent make(NodeEvent::Kind k) const {
    NodeEvent e;
    e.kind = k;
    e.state = agent_.state();
    e.led = agent_.led();
    e.durable = agent_.durable();
    e.role = agent_.election().role;
    return e;
  }
  void push(const NodeEvent& e) {
    ev_.push_over(e, overflowed_);
  }

  static constexpr std::size_t kMaxSeenRelays = 16;

  Config cfg_;
  AgentCore agent_;
  std::optional<MasterCore> master_;
  DedupeWindow<CopySlots> copies_;  // in front of master_: one copy of each (sender, msgid)
  Message rx_;
  std::string mtx_;                  // the Master core's datagram last polled
  std::vector<MasterTransmit> parting_; // a dropped Master core's datagrams not polled yet (no heap until one)
  std::uint32_t rejected_ = 0, overflowed_ = 0;
  Unrouted unrouted_;
  // What was reported last (raft's prevHardSt / prevSoftSt).
  Durable seen_durable_;
  std::uint32_t seen_durable_rev_ = 0;
  std::uint32_t written_rev_ = 0; // the durable_rev() ready() last had written
  std::uint32_t handed_rev_ = 0;  // the durable_rev() last handed out (ready() or a durable event)
  ElectionRole seen_role_ = ElectionRole::none;
  std::uint16_t seen_leader_ = 0, seen_via_ = 0;
  std::uint32_t seen_following_ = 0;
  std::uint16_t seen_relays_[kMaxSeenRelays] = {};
  std::size_t seen_relay_count_ = 0;
  Ring<NodeEvent, kEventSlots> ev_;
};

}  // namespace ev3proto
