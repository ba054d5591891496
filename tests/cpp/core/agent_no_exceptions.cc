// The agent core as firmware builds it: -fno-exceptions -fno-rtti, no gtest. Drives one agent
// through sync, BEHAVIOUR, START, a duplicate, losing the master (PAUSED, then PANIC) and resync,
// and exits non-zero on the first failed check.
#include <cstdio>
#include <cstring>
#include <string_view>

#include "fixed_timers.hpp"
#include "ev3proto/agent.hpp"
#include "ev3proto/durable.hpp"

#include "../firmware_check.hpp"

namespace {
using namespace ev3proto;

// Static storage only: the agent is a global-free local of main, the table is constexpr.
constexpr BehaviourSpec kBehaviours[] = {{"explore", 1u}};

template <typename A>
std::size_t drain(A& a, char (&last)[64]) {
  Transmit t;
  std::size_t n = 0;
  while (a.poll_transmit(t)) {
    const std::size_t k = t.bytes.size() < 63 ? t.bytes.size() : 63;
    std::memcpy(last, t.bytes.data(), k);
    last[k] = '\0';
    ++n;
  }
  AgentEvent e;
  while (a.poll_event(e)) {
  }
  return n;
}
}  // namespace

int main() {
  AgentConfig cfg;
  cfg.timers = ev3test::fixed_timers();
  cfg.caps = Capabilities{"A", kBehaviours, 1, 1u};
  cfg.temp_id = 50007;
  Agent<> agent(cfg, 0);
  char last[64] = {};

  CHECK(agent.state() == State::IDLE && agent.led() == Led::YELLOW_BLINK);
  agent.advance(1000);
  CHECK(drain(agent, last) == 1 && std::strcmp(last, "50007:0:1:1:A") == 0);  // AGENT broadcast

  CHECK(agent.handle_datagram("1:7:10:2:50007", 1, 1100).action == Action::RecvMaster);
  CHECK(agent.state() == State::ACTIVE && agent.id() == 7);
  CHECK(drain(agent, last) == 1 && std::strcmp(last, "7:1:2:3:10") == 0);  // ACK from the new id

  CHECK(agent.handle_datagram("1:7:11:7:explore:speed=3", 1, 1200).action == Action::RecvBehaviour);
  CHECK(drain(agent, last) == 1 && std::strcmp(last, "7:1:3:3:11") == 0);
  CHECK(agent.handle_datagram("1:7:12:8", 1, 1300).action == Action::RecvStart);
  CHECK(agent.state() == State::WORKING && agent.motors());
  CHECK(agent.behaviour().name == "explore" && agent.behaviour().arg(0) == "speed=3");
  drain(agent, last);
  CHECK(agent.handle_datagram("1:7:12:8", 1, 1301).action == Action::RecvDuplicate);  // copy: answered again
  CHECK(drain(agent, last) == 1 && std::strcmp(last, "7:1:5:3:12") == 0);

  // The master goes silent: WORKING -> PAUSED at loss, PANIC at paused.
  agent.advance(1300 + cfg.timers[Timer::loss]);
  CHECK(agent.state() == State::PAUSED && !agent.motors());
  agent.advance(1300 + cfg.timers[Timer::paused]);
  CHECK(agent.state() == State::PANIC && agent.led() == Led::RED_BLINK);
  drain(agent, last);
  CHECK(std::strncmp(last, "7:0:", 4) == 0);  // PANIC broadcast from the old id

  // The master returns and gives the id back.
  CHECK(agent.handle_datagram("1:7:40:2:7", 2, 9000).action == Action::RecvMaster);
  CHECK(agent.state() == State::ACTIVE && agent.behaviour().name.empty());

  // The durable state's text and rule (durable.hpp) build the same way: fixed buffers, no heap.
  Durable d;
  d.epoch = 5;
  d.voted_for = 7;
  d.mepoch = 4;
  d.floor = 5;
  d.members[d.member_count++] = 7;
  Durable back;
  DurableError why;
  CHECK(parse_durable(durable_text(d).view(), back, why) && back == d);
  CHECK(!parse_durable("epoch=5\nvoted_for=0\nmembers=7\nmembers_epoch=4\nfloor=3\n", back, why) &&
        why.view() == "floor: 3 is below members_epoch 4 (learning a membership raises the floor to its epoch)");
  std::printf("agent core, -fno-exceptions -fno-rtti: ok (sizeof(Agent<>) = %zu bytes)\n", sizeof agent);
  return 0;
}
