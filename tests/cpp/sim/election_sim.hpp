// Relay and election over the simulated network (Election.tla in the real cores): a PC master
// (may crash and come back as a candidate) and N robot nodes (node.hpp: the agent core and the
// Master core it runs once it wins an epoch, as the firmware runs them). Links can be cut. The network and the event loop are sim_net.hpp's. The agents' trace hook checks
// fencing on every command acted on (Election StaleMasterFencedInv).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "ev3proto/master.hpp"
#include "ev3proto/node.hpp"
#include "sim_net.hpp"

namespace ev3sim {

class ElectionFleet;

/// The PC's trace sink: each BecomeMaster goes into the history as it happens (the PC may win an
/// epoch and stand for the next, Reconfigure, within one call: its role afterwards misses it).
struct PcWins {
  static constexpr bool enabled = true;
  std::function<void(std::uint32_t)> won;
  void record(const MasterTraceRecord& r) {
    if (r.action == Action::BecomeMaster && won) won(r.epoch_after);
  }
};

/// Agent trace sink: every command that takes effect is checked against the history of elections.
struct FenceCheck {
  static constexpr bool enabled = true;
  ElectionFleet* fleet = nullptr;
  std::size_t index = 0;
  template <typename A>
  void record(const AgentTraceRecord& r, const A&);
};

using SimNode = ev3proto::Node<FenceCheck>;
using SimAgent = SimNode::AgentCore;

class ElectionFleet {
 public:
  static constexpr Peer kPcPeer = 1000;
  static Peer agent_peer(std::size_t i) { return ev3sim::agent_peer(i); }

  ElectionFleet(std::size_t n, std::uint64_t seed, NetConfig net, Timers timers = Timers{})
      : net_(seed, net), timers_(timers) {
    std::vector<AgentConfig> configs = net_.agents(n, timers_);
    for (std::size_t i = 0; i < n; ++i) {
      AgentConfig& c = configs[i];
      c.election.enabled = true;
      c.election.score = static_cast<std::uint32_t>(10 + (i * 7) % n);  // distinct, arbitrary order
      auto node = std::make_unique<Robot>();
      node->trace.fleet = this;
      node->trace.index = i;
      node->node = std::make_unique<SimNode>(SimNode::Config{c, {}}, net_.now(), &node->trace);
      nodes_.push_back(std::move(node));
    }
    MasterConfig c;
    c.timers = timers_;
    c.election = true;
    pc_wins_.won = [this](std::uint32_t e) { note_master(e, kMasterId); };
    pc_ = std::make_unique<Pc>(c, net_.now(), &pc_wins_);
    elected_[1] = kMasterId;
  }

  /// The PC crashes; its epoch, ids, msgids and membership are on stable storage.
  void crash_pc() {
    pc_store_ = MasterConfig{};
    pc_store_.timers = timers_;
    pc_store_.election = true;
    pc_store_.next_id = pc_->next_id();
    pc_store_.next_msgid = pc_->next_msgid();
    pc_store_.epoch = pc_->epoch();
    pc_store_.members = pc_->members();  // its state file: the membership of its epoch
    pc_store_.members_epoch = pc_->members_epoch();
    pc_store_.candidate = true;
    pc_.reset();
  }
  /// The PC comes back as a candidate (Election Restart(PC)).
  void restart_pc() { pc_ = std::make_unique<Pc>(pc_store_, net_.now(), &pc_wins_); }

  void cut(Peer a, Peer b) { down_.insert({std::min(a, b), std::max(a, b)}); }
  void heal(Peer a, Peer b) { down_.erase({std::min(a, b), std::max(a, b)}); }

  void run_until(Millis until, const std::function<void(ElectionFleet&)>& check) { net_.run_until(until, *this, check); }

  /// An operator command at the PC (when it is up).
  void pc_command(std::uint16_t agent, const Command& c) {
    if (pc_) pc_->command(agent, c, net_.now());
    flush();
  }
  /// An operator command at agent @p i's Master core (when it runs one).
  void agent_master_command(std::size_t i, std::uint16_t agent, const Command& c) {
    nodes_[i]->node->command(agent, c, net_.now());
    flush();
  }

  Millis now() const { return net_.now(); }
  std::size_t size() const { return nodes_.size(); }
  const SimAgent& agent(std::size_t i) { return nodes_[i]->node->agent(); }
  const Master<>* agent_master(std::size_t i) { return nodes_[i]->node->master(); }
  Master<PcWins>* pc() { return pc_.get(); }
  const Timers& timers() const { return timers_; }
  /// History: the master of each epoch (Election elected).
  const std::map<std::uint32_t, std::uint16_t>& elected() const { return elected_; }
  /// The first violation seen, or "".
  std::string failure;
  /// Commands acted on (checked).
  std::size_t applied = 0;
  std::vector<OperatorEvent> ops;

  /// Election AtMostOneMasterPerEpochInv over the history, recorded at every step.
  void note_master(std::uint32_t epoch, std::uint16_t who) {
    const auto it = elected_.find(epoch);
    if (it == elected_.end()) {
      elected_[epoch] = who;
    } else if (it->second != who && failure.empty()) {
      failure = "two masters in epoch " + std::to_string(epoch) + ": " + std::to_string(it->second) +
                " and " + std::to_string(who) + " at " + std::to_string(net_.now());
    }
  }

  /// A command took effect at agent @p i: fenced (its epoch is the highest the agent had seen)
  /// and from the master elected in that epoch (Election StaleMasterFencedInv).
  void note_applied(std::size_t i, std::string_view msg, std::uint32_t seen) {
    ++applied;
    Message m;
    if (!decode(msg, m).ok()) return;
    std::uint32_t e = 1;
    if (m.type == MsgType::EPOCH_CMD) e = m.param_u32(0).value_or(0);
    const auto it = elected_.find(e);
    if (failure.empty() && (e != seen || it == elected_.end() || it->second != m.sender))
      failure = "agent " + std::to_string(i) + " acted on " + std::string(msg) + " (epoch " +
                std::to_string(e) + ") having seen epoch " + std::to_string(seen) + " at " +
                std::to_string(net_.now());
  }

 private:
  struct Robot {
    FenceCheck trace;
    std::unique_ptr<SimNode> node;
  };
  friend class SimNet;  // the event loop: next_deadline, deliver, advance, flush

  Millis next_deadline() const {
    Millis next = ~Millis{0};
    if (pc_) next = std::min(next, pc_->next_deadline());
    for (auto& nd : nodes_) next = std::min(next, nd->node->next_deadline());
    return next;
  }
  void advance(Millis now) {
    if (pc_) pc_->advance(now);
    for (auto& nd : nodes_) nd->node->advance(now);
  }

  bool linked(Peer a, Peer b) const { return down_.count({std::min(a, b), std::max(a, b)}) == 0; }

  void deliver(const Packet& p) {
    if (!linked(p.from, p.to)) return;
    if (p.to == kPcPeer) {
      if (pc_) pc_->handle_datagram(p.bytes, p.from, net_.now());
      return;
    }
    nodes_[p.to - 1]->node->handle_datagram(p.bytes, p.from, net_.now());
  }

  void transmit(Peer from, Peer to, const std::string& bytes) { net_.transmit(from, to, bytes); }
  void broadcast(Peer from, const std::string& b) {
    if (from != kPcPeer) transmit(from, kPcPeer, b);
    for (std::size_t j = 0; j < nodes_.size(); ++j)
      if (agent_peer(j) != from) transmit(from, agent_peer(j), b);
  }

  /// Every output onto the network; the history of masters per epoch.
  void flush() {
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
      SimNode& nd = *nodes_[i]->node;
      if (nd.agent().election().role == ElectionRole::master) note_master(nd.agent().election().master_epoch, nd.agent().id());
      NodeEvent e;
      while (nd.poll_event(e)) {
      }
      NodeTransmit t;
      while (nd.poll_transmit(t)) {
        const std::string b(t.bytes);
        if (t.dest == Dest::broadcast) broadcast(agent_peer(i), b);
        else transmit(agent_peer(i), t.peer, b);
      }
      OperatorEvent oe;
      while (nd.poll_operator_event(oe)) ops.push_back(oe);
    }
    if (pc_) {
      if (pc_->role() == MasterRole::master) note_master(pc_->epoch(), kMasterId);
      drain_master(*pc_, kPcPeer);
    }
  }
  template <typename M>
  void drain_master(M& m, Peer self) {
    MasterTransmit mt;
    while (m.poll_transmit(mt)) {
      if (mt.dest == Dest::broadcast) broadcast(self, mt.bytes);
      else transmit(self, mt.peer, mt.bytes);
    }
    OperatorEvent oe;
    while (m.poll_event(oe)) ops.push_back(oe);
  }

  SimNet net_;
  Timers timers_;
  std::vector<std::unique_ptr<Robot>> nodes_;
  using Pc = Master<PcWins>;
  PcWins pc_wins_;
  std::unique_ptr<Pc> pc_;
  MasterConfig pc_store_;
  std::set<std::pair<Peer, Peer>> down_;
  std::map<std::uint32_t, std::uint16_t> elected_;
};

template <typename A>
void FenceCheck::record(const AgentTraceRecord& r, const A&) {
  Action a = r.action == Action::ApplyCommand ? r.cmd : r.action;
  if (a >= Action::RecvBehaviour && a <= Action::RecvRestart && r.after.win_rev != r.before.win_rev)
    fleet->note_applied(index, r.msg, r.before.epoch);
}

}  // namespace ev3sim
