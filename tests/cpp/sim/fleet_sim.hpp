// A deterministic multi-node harness (quinn's `Pair` idea, for a fleet): one Master and N Agents
// wired through a simulated network with a seeded loss / duplication / reordering schedule and a
// virtual clock. Each datagram is sent 3 times like the real transport; every copy is lost,
// delayed (which reorders) or duplicated independently. The clock jumps from event to event (the
// nodes' deadlines, deliveries), so a minute of fleet time runs in milliseconds. `check` runs the
// invariants after every step.
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

namespace ev3sim {

using namespace ev3proto;

/// The network's behaviour.
struct NetConfig {
  double loss = 0.0;         ///< Probability each copy is lost.
  double dup = 0.0;          ///< Probability each copy arrives twice.
  Millis min_delay = 1;      ///< Delay of a copy: uniform in [min_delay, max_delay] (reorders).
  Millis max_delay = 20;
  int copies = 3;            ///< Copies per datagram (the transport's rule).
};

class Fleet {
 public:
  static constexpr Peer kMasterPeer = 1000;
  static Peer agent_peer(std::size_t i) { return static_cast<Peer>(i + 1); }

  Fleet(std::size_t n, std::uint64_t seed, NetConfig net, Timers timers = Timers{})
      : rng_(seed), net_(net), timers_(timers) {
    caps_ = Capabilities{"A", kBehaviours, 1, 1u};
    std::set<std::uint16_t> temps;
    std::uniform_int_distribution<std::uint32_t> tid(kFirstTempId, 65535);
    for (std::size_t i = 0; i < n; ++i) {
      std::uint16_t t;
      do t = static_cast<std::uint16_t>(tid(rng_)); while (!temps.insert(t).second);
      AgentConfig c;
      c.caps = caps_;
      c.timers = timers_;
      c.temp_id = t;
      agents_.push_back(std::make_unique<Agent<>>(c, now_));
    }
    restart_master();
  }

  /// The master crashes: its registry is lost, datagrams to it are dropped.
  void crash_master() {
    next_id_ = master_->next_id();
    next_msgid_ = master_->next_msgid();
    master_.reset();
    crashed_at_ = now_;
  }
  /// The master restarts with an empty registry, ids and msgids from "stable storage".
  void restart_master() {
    MasterConfig c;
    c.timers = timers_;
    c.next_id = next_id_;
    c.next_msgid = next_msgid_;
    master_ = std::make_unique<Master<>>(c, now_);
  }

  /// Runs until @p until, stepping event to event and calling @p check after every step.
  void run_until(Millis until, const std::function<void(Fleet&)>& check) {
    for (;;) {
      Millis next = until;
      if (master_) next = std::min(next, master_->next_deadline());
      for (auto& a : agents_) next = std::min(next, a->next_deadline());
      if (!inflight_.empty()) next = std::min(next, std::get<0>(inflight_.begin()->first));
      if (next < now_) next = now_;
      now_ = next;
      // Deliver everything due now, then let every node's time move.
      while (!inflight_.empty() && std::get<0>(inflight_.begin()->first) <= now_) {
        const auto it = inflight_.begin();
        const Packet p = it->second;
        inflight_.erase(it);
        deliver(p);
        flush();
        if (check) check(*this);
      }
      if (master_) master_->advance(now_);
      for (auto& a : agents_) a->advance(now_);
      flush();
      if (check) check(*this);
      if (now_ >= until) break;
    }
  }

  /// An operator command (0 = all agents).
  void command(std::uint16_t agent, const Command& c) {
    if (master_) master_->command(agent, c, now_);
    flush();
  }

  /// Changes the loss probability from now on (1.0: a partition; the nodes keep running).
  void set_loss(double loss) { net_.loss = loss; }

  Millis now() const { return now_; }
  Agent<>& agent(std::size_t i) { return *agents_[i]; }
  std::size_t size() const { return agents_.size(); }
  Master<>* master() { return master_.get(); }
  const Timers& timers() const { return timers_; }
  Millis crashed_at() const { return crashed_at_; }
  std::size_t inflight() const { return inflight_.size(); }
  /// Operator events seen so far.
  std::vector<OperatorEvent> ops;

 private:
  static constexpr BehaviourSpec kBehaviours[] = {{"explore", 1u}};

  struct Packet {
    Peer from = 0, to = 0;
    std::string bytes;
  };

  void deliver(const Packet& p) {
    if (p.to == kMasterPeer) {
      if (master_) master_->handle_datagram(p.bytes, p.from, now_);
      return;
    }
    agents_[p.to - 1]->handle_datagram(p.bytes, p.from, now_);
  }

  /// Puts a datagram on the wire: `copies` copies, each lost, delayed, duplicated at random.
  void transmit(Peer from, Peer to, const std::string& bytes) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::uniform_int_distribution<Millis> delay(net_.min_delay, net_.max_delay);
    for (int c = 0; c < net_.copies; ++c) {
      if (u(rng_) < net_.loss) continue;
      const int n = u(rng_) < net_.dup ? 2 : 1;
      for (int k = 0; k < n; ++k) inflight_.emplace(std::make_tuple(now_ + delay(rng_), seq_++), Packet{from, to, bytes});
    }
  }

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

  std::mt19937_64 rng_;
  NetConfig net_;
  Timers timers_;
  Capabilities caps_;
  Millis now_ = 0;
  std::uint64_t seq_ = 0;
  std::map<std::tuple<Millis, std::uint64_t>, Packet> inflight_;
  std::vector<std::unique_ptr<Agent<>>> agents_;
  std::unique_ptr<Master<>> master_;
  std::uint16_t next_id_ = kFirstAssignedId;
  std::uint32_t next_msgid_ = 1;
  Millis crashed_at_ = 0;
};

}  // namespace ev3sim
