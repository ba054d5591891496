// libFuzzer target: the agent core (ev3proto/agent.hpp), with or without the election, fed any
// sequence of inputs the input spells: datagrams (mostly well-formed, from the protocol's words;
// some raw bytes), time passing, and the robot's inputs (action done or failed, devices unplugged
// and plugged back, battery low). After every step the C++ forms of Agent.tla's invariants must
// hold and every datagram the core sends must decode canonically; anything else traps.
// Also linked with replay_main.cpp to run the committed corpus under gcc and armel.
#include <cstddef>
#include <cstdint>
#include <string>

#include "ev3proto/agent.hpp"
#include "fuzz_input.hpp"
#include "invariants.hpp"

namespace {

using namespace ev3proto;

constexpr BehaviourSpec kBehaviours[] = {{"explore", 1u}, {"wait", 0u}};
constexpr std::uint16_t kTemp = 50001;
constexpr std::uint16_t kIds[] = {0, 1, 2, 3, 7, kTemp, 50002};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fuzzin::Reader in{data, size};
  AgentConfig c;
  c.caps = Capabilities{"A", kBehaviours, 2, 1u};
  c.temp_id = kTemp;
  c.first_msgid = 1u + in.byte();
  c.election.enabled = (in.byte() & 1) != 0;
  static Agent<>* a = nullptr;  // about 100 KB with its report buffer: off the fuzzer's stack
  delete a;
  a = new Agent<>(c, 0);
  Millis now = 0;
  std::uint32_t base = 1;
  while (in.n > 0) {
    if (!fuzzin::shared_step(in.byte() % 8, in, *a, kIds, base, now, 6000)) {
      switch (in.byte() % 6) {  // the robot's inputs
        case 0: a->action_ok(now); break;
        case 1: a->action_interrupted(Warning::OBSTACLE_DETECTED, now); break;
        case 2: a->action_failed("stalled", now); break;
        case 3: a->device_unplugged(1u, "in1", now); break;
        case 4: a->device_plugged(1u, "in1", now); break;
        default: a->battery_low(now); break;
      }
    }
    Transmit t;
    while (a->poll_transmit(t)) fuzzin::check_output(t.bytes);
    AgentEvent e;
    while (a->poll_event(e)) {
    }
    fuzzin::check_agent(*a, now, c.timers);
  }
  return 0;
}
