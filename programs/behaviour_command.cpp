// The console's BEHAVIOUR commands made ready to send: the one part of the console that reads a
// file (a `custom @FILE` definition); the check itself is the library's (behaviour/request.hpp).
#include <memory>

#include <ev3proto/behaviour/print.hpp>
#include <ev3proto/behaviour/request.hpp>

#include "ev3io/state_file.hpp"
#include "ev3prog/console.hpp"

namespace ev3prog {

using ev3proto::MsgType;

std::string prepare_behaviour(ConsoleCommand& c) {
  using namespace ev3proto::behaviour;
  if (c.kind != ConsoleCommand::Kind::send || c.command.type != MsgType::BEHAVIOUR) return {};
  std::string text;
  const std::string where = c.file.empty() ? "behaviour " + c.command.name : c.file;
  if (!c.file.empty()) {
    std::vector<std::string> lines;
    std::string err;
    if (!ev3io::read_lines(c.file, lines, err)) return err.empty() ? "cannot read " + c.file + ": no such file" : err;
    for (const std::string& l : lines) text += l + "\n";
  }
  std::vector<std::string_view> args(c.command.args.begin(), c.command.args.end());
  const auto def = std::make_unique<Definition>();
  char buf[kMaxMessage * 2];
  Text why(buf, sizeof buf);
  const std::string refused = "refused before sending: " + where + ": ";
  if (c.file.empty()) {  // a built-in: travels by name, checked here as the robot checks it
    if (!resolve_request(c.command.name, args.data(), args.size(), kModelA, kModelA.devices, *def, why))
      return refused + std::string(why.view());
    return {};
  }
  // A custom definition is parsed once: written in its compact form (no comments; ';' for a new line
  // costs one byte, not three) before the arguments, which travel after it, are applied and checked.
  Diagnostic d;
  if (!parse(text, *def, d)) {
    write(why, d);
    return refused + std::string(why.view());
  }
  std::string compact_text(kMaxSource * 2, '\0');
  Text out(compact_text.data(), compact_text.size());
  compact(out, *def);
  compact_text.resize(out.size());
  if (!apply_and_check(*def, args.data(), args.size(), kModelA, kModelA.devices, why))
    return refused + std::string(why.view());
  char dgram[ev3proto::kMaxDatagram];
  if (custom_datagram_size(compact_text, dgram) == 0)
    return refused + "too long for one datagram (" + std::to_string(compact_text.size()) +
           " bytes in compact form; a datagram holds " + std::to_string(ev3proto::kMaxDatagram) + ")";
  c.command.args.insert(c.command.args.begin(), std::move(compact_text));
  return {};
}

}  // namespace ev3prog
