// libFuzzer target: the master core (ev3proto/master.hpp), with or without the election, fed any
// sequence of inputs the input spells: datagrams from agents and strangers (mostly well-formed, from
// the protocol's words; some raw bytes), the operator's commands (to one agent, to all, to ids it
// does not know) and time passing. After every step the C++ forms of Master.tla's invariants must
// hold, its epoch never goes back and its state file reads back, and every datagram the core sends
// must decode canonically; anything else traps.
// Also linked with replay_main.cpp to run the committed corpus under gcc and armel.
#include <cstddef>
#include <cstdint>
#include <string>

#include "ev3proto/master.hpp"
#include "fuzz_input.hpp"
#include "invariants.hpp"

namespace {

using namespace ev3proto;
using fuzzin::violation;

constexpr std::uint16_t kIds[] = {0, 1, 2, 3, 4, 50001, 50002, 50003};
constexpr MsgType kCommands[] = {MsgType::BEHAVIOUR, MsgType::START,   MsgType::STOP,     MsgType::PAUSE,
                                 MsgType::RESUME,    MsgType::STANDBY, MsgType::CONTINUE, MsgType::RESTART};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fuzzin::Reader in{data, size};
  MasterConfig c;
  const std::uint8_t config = in.byte();
  c.election = (config & 1) != 0;
  if (c.election && (config & 2) != 0) c.members = {2, 3, 4};  // the PC with a membership
  c.drop_copies = (in.byte() & 1) != 0;
  Master<> m(c, 0);
  Millis now = 0;
  std::uint32_t base = 1;
  MasterDurable durable = m.durable();
  while (in.n > 0) {
    if (!fuzzin::shared_step(in.byte() % 8, in, m, kIds, base, now, 12000)) {  // the operator's commands
      const MsgType t = kCommands[in.byte() % 8];
      const Command cmd = t == MsgType::BEHAVIOUR ? Command::assign(in.byte() & 1 ? "wait" : "explore", {"seconds=1"})
                                                  : Command::simple(t);
      m.command(kIds[in.byte() % 5], cmd, now);
    }
    MasterTransmit t;
    while (m.poll_transmit(t)) {
      fuzzin::check_output(t.bytes);
      if (t.dest == Dest::peer && t.peer == 0) violation("OutInv: a datagram to no endpoint");
    }
    OperatorEvent e;
    while (m.poll_event(e)) {
    }
    fuzzin::check_master(m, c.election);
    fuzzin::check_master_durable(durable, m.durable());
    durable = m.durable();
  }
  return 0;
}
