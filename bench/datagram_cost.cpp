// Instructions per datagram on the robot, for callgrind: the proxy for the EV3's 300 MHz ARM9
// (docs/benchmarks.md, "Per datagram on the robot"). No timing here: bench/datagram_cost.sh runs
// this under `valgrind --tool=callgrind --toggle-collect=*measured*`, which counts only what the
// node does in measured() (the harness's text formatting and checks left out), and divides by N.
//
//   datagram_cost heartbeat N   an agent node following the PC: per round one heartbeat, its PING
//                               sent (advance) and the PONG received (decode, the node, the agent
//                               core's RecvPong, its dedupe of commands untouched)
//   datagram_cost master N      an elected node (master of epoch 2 of the fleet {7, 8}, 8's vote
//                               fed in): per round 8's PING received (decode once, the copy
//                               window's dedupe, the Master core's MasterPing, the agent core's
//                               ignore) and the PONG encoded
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include <ev3proto/node.hpp>

namespace {

using namespace ev3proto;

constexpr BehaviourSpec kBehs[] = {{"wait", 0}};

Node<>::Config config() {
  Node<>::Config c;
  c.agent.caps = Capabilities{"A", kBehs, 1, 0};
  c.agent.temp_id = 50001;
  c.agent.election.enabled = true;
  c.agent.election.score = 5;
  return c;
}

/// Drains the node; returns how many of the datagrams it sent were PONGs.
std::size_t drain(Node<>& n) {
  std::size_t k = 0;
  NodeTransmit t;
  Message m;
  while (n.poll_transmit(t))
    if (decode(t.bytes, m).ok() && m.type == MsgType::PONG) ++k;
  NodeEvent e;
  while (n.poll_event(e)) {
  }
  OperatorEvent o;
  while (n.poll_operator_event(o)) {
  }
  return k;
}

/// What is counted: with @p tick, the node's clock @p clock moves on a heartbeat and the node sends
/// what is due (the agent's PING); then datagram @p d arrives from @p from one ms later and the
/// node's answers are taken. Returns how many datagrams the node gave.
__attribute__((noinline)) std::size_t measured(Node<>& n, Millis& clock, bool tick, const char* d, Peer from) {
  std::size_t k = 0;
  NodeTransmit t;
  NodeEvent e;
  if (tick) {
    clock += Timers{}[Timer::heartbeat];
    n.advance(clock);
    while (n.poll_transmit(t)) ++k;
    while (n.poll_event(e)) {
    }
  }
  n.handle_datagram(d, from, ++clock);
  while (n.poll_transmit(t)) ++k;
  while (n.poll_event(e)) {
  }
  return k;
}

int heartbeat(unsigned rounds) {
  Node<> n(config(), 0);
  n.handle_datagram("1:7:1:2:50001", 1, 10);  // MASTER: id 7
  drain(n);
  Millis now = 10;
  char pong[64];
  for (unsigned i = 0; i < rounds; ++i) {
    std::snprintf(pong, sizeof pong, "1:7:%u:6:1", 100 + i);
    if (measured(n, now, true, pong, 1) < 1) return std::fprintf(stderr, "datagram_cost: no PING sent\n"), 1;
    if (n.agent().last_heard() != now) return std::fprintf(stderr, "datagram_cost: PONG not taken\n"), 1;
  }
  return is_synced(n.agent().state()) ? 0 : 1;
}

int master(unsigned rounds) {
  Node<> n(config(), 0);
  n.handle_datagram("1:7:1:2:50001", 1, 10);         // MASTER: id 7
  n.handle_datagram("1:0:2:29:1:1:7:8", 1, 20);      // LEADER: the fleet is {7, 8}
  drain(n);
  Millis now = 20;
  bool prevoted = false, voted = false;
  while (n.master() == nullptr && now < 20000) {     // the PC silent: PANIC; 8 pre-votes and votes for 7
    now += 10;
    n.advance(now);
    drain(n);
    const auto& el = n.agent().election();
    if (!prevoted && n.agent().state() == State::PANIC) {
      n.handle_datagram("8:7:1:33:1", 8, now);        // PREVOTE_OK(1)
      prevoted = true;
    } else if (!voted && el.role == ElectionRole::candidate) {
      n.handle_datagram("8:7:2:28:2:7", 8, now);      // VOTE(2, 7)
      voted = true;
    }
    drain(n);
  }
  if (n.master() == nullptr) return std::fprintf(stderr, "datagram_cost: the node was not elected\n"), 1;
  char buf[64];
  std::snprintf(buf, sizeof buf, "8:7:%u:5:ACTIVE", 9u);  // the first PING: its answer checked
  n.handle_datagram(buf, 8, ++now);
  if (drain(n) != 1) return std::fprintf(stderr, "datagram_cost: the elected node does not answer a PING\n"), 1;
  for (unsigned i = 0; i < rounds; ++i) {            // 8 pings its new master
    std::snprintf(buf, sizeof buf, "8:7:%u:5:ACTIVE", 10 + i);
    if (measured(n, now, false, buf, 8) < 1) return std::fprintf(stderr, "datagram_cost: PING %u unanswered\n", i), 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3 || (std::strcmp(argv[1], "heartbeat") != 0 && std::strcmp(argv[1], "master") != 0)) {
    std::fprintf(stderr, "usage: datagram_cost heartbeat|master ROUNDS\n");
    return 2;
  }
  const unsigned rounds = static_cast<unsigned>(std::strtoul(argv[2], nullptr, 10));
  return std::strcmp(argv[1], "heartbeat") == 0 ? heartbeat(rounds) : master(rounds);
}
