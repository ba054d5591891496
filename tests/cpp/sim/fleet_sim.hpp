// A deterministic multi-node harness (quinn's `Pair` idea, for a fleet): one Master and N Agents
// wired through the simulated network of sim_net.hpp (seeded loss / duplication / reordering, 3
// copies per datagram, a virtual clock that jumps from event to event, so a minute of fleet time
// runs in milliseconds). `check` runs the invariants after every step.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "ev3proto/agent.hpp"
#include "ev3proto/master.hpp"
#include "sim_net.hpp"

namespace ev3sim {

using namespace ev3proto;

class Fleet {
 public:
  static constexpr Peer kMasterPeer = 1000;

  Fleet(std::size_t n, std::uint64_t seed, NetConfig net, Timers timers = Timers{})
      : net_(seed, net), timers_(timers) {
    for (const AgentConfig& c : net_.agents(n, timers_)) agents_.push_back(std::make_unique<Agent<>>(c, net_.now()));
    restart_master();
  }

  /// The master crashes: its registry is lost, datagrams to it are dropped.
  void crash_master() {
    next_id_ = master_->next_id();
    next_msgid_ = master_->next_msgid();
    master_.reset();
    crashed_at_ = net_.now();
  }
  /// The master restarts with an empty registry, ids and msgids from "stable storage".
  void restart_master() {
    MasterConfig c;
    c.timers = timers_;
    c.next_id = next_id_;
    c.next_msgid = next_msgid_;
    master_ = std::make_unique<Master<>>(c, net_.now());
  }

  /// Runs until @p until, stepping event to event and calling @p check after every step.
  void run_until(Millis until, const std::function<void(Fleet&)>& check) { net_.run_until(until, *this, check); }

  /// An operator command (0 = all agents).
  void command(std::uint16_t agent, const Command& c) {
    if (master_) master_->command(agent, c, net_.now());
    flush();
  }

  /// Changes the loss probability from now on (1.0: a partition; the nodes keep running).
  void set_loss(double loss) { net_.set_loss(loss); }

  Millis now() const { return net_.now(); }
  Agent<>& agent(std::size_t i) { return *agents_[i]; }
  std::size_t size() const { return agents_.size(); }
  Master<>* master() { return master_.get(); }
  const Timers& timers() const { return timers_; }
  Millis crashed_at() const { return crashed_at_; }
  std::size_t inflight() const { return net_.inflight(); }
  /// Operator events seen so far.
  std::vector<OperatorEvent> ops;

 private:

  friend class SimNet;  // the event loop: next_deadline, deliver, advance, flush

  Millis next_deadline() const {
    Millis next = ~Millis{0};
    if (master_) next = std::min(next, master_->next_deadline());
    for (auto& a : agents_) next = std::min(next, a->next_deadline());
    return next;
  }
  void advance(Millis now) {
    if (master_) master_->advance(now);
    for (auto& a : agents_) a->advance(now);
  }

  void deliver(const Packet& p) {
    if (p.to == kMasterPeer) {
      if (master_) master_->handle_datagram(p.bytes, p.from, net_.now());
      return;
    }
    agents_[p.to - 1]->handle_datagram(p.bytes, p.from, net_.now());
  }

  void transmit(Peer from, Peer to, const std::string& bytes) { net_.transmit(from, to, bytes); }

  /// Moves every node's outputs onto the network (and operator events into `ops`).
  void flush() {
    for (std::size_t i = 0; i < agents_.size(); ++i) {
      Transmit t;
      while (agents_[i]->poll_transmit(t)) {
        const std::string b(t.bytes);
        if (t.dest == Dest::broadcast) {
          transmit(agent_peer(i), kMasterPeer, b);
          for (std::size_t j = 0; j < agents_.size(); ++j)
            if (j != i) transmit(agent_peer(i), agent_peer(j), b);
        } else {
          transmit(agent_peer(i), t.peer, b);
        }
      }
      AgentEvent e;
      while (agents_[i]->poll_event(e)) {
      }
    }
    if (!master_) return;
    MasterTransmit mt;
    while (master_->poll_transmit(mt)) transmit(kMasterPeer, mt.peer, mt.bytes);
    OperatorEvent oe;
    while (master_->poll_event(oe)) ops.push_back(oe);
  }

  SimNet net_;
  Timers timers_;
  std::vector<std::unique_ptr<Agent<>>> agents_;
  std::unique_ptr<Master<>> master_;
  std::uint16_t next_id_ = kFirstAssignedId;
  std::uint32_t next_msgid_ = 1;
  Millis crashed_at_ = 0;
};

}  // namespace ev3sim
