// The simulated network and virtual clock that both multi-node harnesses (fleet_sim.hpp,
// election_sim.hpp) step: each datagram is put on the wire 3 times like the real transport, every
// copy lost, delayed (which reorders) or duplicated independently by a seeded schedule, and the
// clock jumps from event to event (the nodes' deadlines, deliveries). The event loop is written
// once here; a harness says how to reach its nodes.
#pragma once

#include <algorithm>
#include <cstdint>
#include <map>
#include <random>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "ev3proto/agent.hpp"
#include "ev3proto/core.hpp"

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

/// The peer handle of agent @p i in both harnesses (the master's, the PC's, is 1000).
inline Peer agent_peer(std::size_t i) { return static_cast<Peer>(i + 1); }

/// What the simulated robots offer: model A with one behaviour needing device bit 1.
inline constexpr BehaviourSpec kSimBehaviours[] = {{"explore", 1u}};

/// One copy of a datagram on the wire.
struct Packet {
  Peer from = 0, to = 0;
  std::string bytes;
};

class SimNet {
 public:
  SimNet(std::uint64_t seed, NetConfig net) : rng_(seed), net_(net) {}

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

  /// Configurations of @p n agents (model A, kSimBehaviours, @p timers) with distinct temporary ids
  /// drawn from the seeded generator, before any datagram.
  std::vector<AgentConfig> agents(std::size_t n, const Timers& timers) {
    std::vector<AgentConfig> out;
    std::set<std::uint16_t> temps;
    std::uniform_int_distribution<std::uint32_t> tid(kFirstTempId, 65535);
    for (std::size_t i = 0; i < n; ++i) {
      std::uint16_t t;
      do t = static_cast<std::uint16_t>(tid(rng_)); while (!temps.insert(t).second);
      AgentConfig c;
      c.caps = Capabilities{"A", kSimBehaviours, 1, 1u};
      c.timers = timers;
      c.temp_id = t;
      out.push_back(c);
    }
    return out;
  }

  /// The event loop of @p fleet until @p until: the clock jumps to the next event (a node's
  /// deadline, fleet.next_deadline(), or a delivery); every copy due is delivered
  /// (fleet.deliver(packet)), then every node's time moves (fleet.advance(now)). After each delivery
  /// and each advance, fleet.flush() moves the nodes' outputs onto the wire and @p check runs.
  template <typename Fleet, typename Check>
  void run_until(Millis until, Fleet& fleet, const Check& check) {
    for (;;) {
      Millis next = std::min(until, fleet.next_deadline());
      if (!inflight_.empty()) next = std::min(next, std::get<0>(inflight_.begin()->first));
      if (next < now_) next = now_;
      now_ = next;
      while (!inflight_.empty() && std::get<0>(inflight_.begin()->first) <= now_) {
        const auto it = inflight_.begin();
        const Packet p = it->second;
        inflight_.erase(it);
        fleet.deliver(p);
        fleet.flush();
        if (check) check(fleet);
      }
      fleet.advance(now_);
      fleet.flush();
      if (check) check(fleet);
      if (now_ >= until) break;
    }
  }

  Millis now() const { return now_; }
  std::size_t inflight() const { return inflight_.size(); }
  /// Changes the loss probability from now on (1.0: a partition; the nodes keep running).
  void set_loss(double loss) { net_.loss = loss; }

 private:
  std::mt19937_64 rng_;
  NetConfig net_;
  Millis now_ = 0;
  std::uint64_t seq_ = 0;
  std::map<std::tuple<Millis, std::uint64_t>, Packet> inflight_;
};

}  // namespace ev3sim
