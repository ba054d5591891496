// libFuzzer target: the robot node (ev3proto/node.hpp: the agent core with the election, and the
// Master core it runs while elected), fed any sequence of inputs the input spells: datagrams of
// every type (election and relay ones too, from the protocol's words; some raw bytes), time
// passing, device events, and operator commands (taken only while the node is master). Every
// output goes through ready(), as the programs do. After every step: Agent.tla's invariants on the
// agent core, Master.tla's on a running Master core, which runs exactly while the agent is master
// of that epoch; the durable state only moves forward (epoch, one vote per epoch, membership epoch,
// floor), reads back as a state file and is written before any datagram goes out; the Master
// core's state file reads back; every datagram decodes canonically.
// Also linked with replay_main.cpp to run the committed corpus under gcc and armel.
#include <cstddef>
#include <cstdint>
#include <string>

#include "ev3proto/node.hpp"
#include "fuzz_input.hpp"
#include "invariants.hpp"

namespace {

using namespace ev3proto;
using fuzzin::violation;

constexpr BehaviourSpec kBehaviours[] = {{"explore", 1u}, {"wait", 0u}};
constexpr std::uint16_t kTemp = 50001;
constexpr std::uint16_t kIds[] = {0, 1, 2, 3, 4, 7, kTemp};
constexpr MsgType kCommands[] = {MsgType::BEHAVIOUR, MsgType::START, MsgType::STOP, MsgType::PAUSE,
                                 MsgType::RESUME};

/// The durable state moves only forward: @p now after @p before.
void check_durable(const Durable& before, const Durable& now) {
  if (now.epoch < before.epoch) violation("the epoch went back");
  if (now.epoch == before.epoch && before.voted_for != 0 && now.voted_for != before.voted_for)
    violation("a second vote in one epoch");
  if (now.mepoch < before.mepoch) violation("an older membership replaced a newer one");
  if (now.floor < before.floor) violation("the floor went down");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fuzzin::Reader in{data, size};
  Node<>::Config c;
  c.agent.caps = Capabilities{"A", kBehaviours, 2, 1u};
  c.agent.temp_id = kTemp;
  c.agent.first_msgid = 1u + in.byte();
  c.agent.election.enabled = true;
  c.agent.election.score = in.byte() % 40u;
  static Node<>* n = nullptr;  // two cores and their windows: off the fuzzer's stack
  delete n;
  n = new Node<>(c, 0);
  Millis now = 0;
  std::uint32_t base = 1;
  Durable written = n->agent().durable();
  while (in.n > 0) {
    if (!fuzzin::shared_step(in.byte() % 8, in, *n, kIds, base, now, 6000)) {
      if (in.byte() & 1) {
        switch (in.byte() % 5) {  // the robot's inputs
          case 0: n->device_unplugged(1u, "in1", now); break;
          case 1: n->device_plugged(1u, "in1", now); break;
          case 2: n->action_ok(now); break;
          case 3: n->robot_event(RobotEventKind::OBSTACLE_DETECTED, "in4", now); break;
          default: n->battery_low(now); break;
        }
      } else {  // the operator's commands, while master
        const MsgType t = kCommands[in.byte() % 5];
        n->command(kIds[in.byte() % 6], t == MsgType::BEHAVIOUR ? Command::assign("wait", {"seconds=1"})
                                                               : Command::simple(t), now);
      }
    }
    const bool ok = n->ready(
        [&](const Durable& d) {
          check_durable(written, d);
          fuzzin::check_agent_durable_text(d);
          written = d;
          return true;
        },
        [&](const NodeTransmit& t) {
          if (!(written == n->agent().durable())) violation("a datagram before its durable state");
          fuzzin::check_output(t.bytes);
        });
    if (!ok) violation("ready() refused with every write succeeding");
    NodeEvent e;
    while (n->poll_event(e)) {
    }
    fuzzin::check_agent(n->agent(), now, c.agent.timers);
    const auto& el = n->agent().election();
    if (el.role == ElectionRole::master &&
        (n->master() == nullptr || n->master()->epoch() != el.master_epoch))
      violation("master of an epoch without its Master core");
    if (n->master() != nullptr) {
      fuzzin::check_master(*n->master(), true);
      fuzzin::check_master_durable_text(n->master()->durable());
    }
  }
  return 0;
}
