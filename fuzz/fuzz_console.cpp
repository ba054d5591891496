// libFuzzer target: the operator's console language (programs/console.cpp: what ev3-master and an
// elected ev3-agent read from the terminal, a --script or a --master-script), one line at a time.
// Every line is refused with a reason or parsed into a command; a parsed `behaviour` (built-in:
// `custom @FILE` would read a file) is checked as a robot of model A checks it on receipt, and what
// passes encodes as the BEHAVIOUR datagram it becomes (or is refused as too long, never as
// malformed); a parsed rule switches the explore-exploit rule on or says why not.
// Also linked with replay_main.cpp to run the committed corpus under gcc and armel.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "ev3prog/console.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  for (std::size_t pos = 0; pos <= input.size();) {  // one line after another, as a script's
    std::size_t nl = input.find('\n', pos);
    if (nl == std::string_view::npos) nl = input.size();
    const std::string_view line = input.substr(pos, nl - pos);
    pos = nl + 1;
    ev3prog::ConsoleCommand c;
    const std::string err = ev3prog::parse_console_line(line, c);
    if (!err.empty()) continue;
    using K = ev3prog::ConsoleCommand::Kind;
    if (c.kind == K::send && c.command.type == ev3proto::MsgType::BEHAVIOUR && c.file.empty()) {
      if (!ev3prog::prepare_behaviour(c).empty()) continue;  // refused with a reason, before sending
      std::vector<std::string_view> p{c.command.name};
      for (const std::string& a : c.command.args) p.push_back(a);
      char buf[ev3proto::kMaxDatagram];
      const ev3proto::EncodeResult r = ev3proto::encode_parts(1, c.agent, 1, static_cast<std::uint8_t>(c.command.type),
                                                              p.data(), p.size(), buf, sizeof buf);
      if (!r.ok() && r.reason != ev3proto::Reason::too_long) fuzzin::violation("a behaviour the console took does not encode");
    }
    if (c.kind == K::rule && !c.colour.empty()) {
      ev3proto::ExploreExploit rule;
      const std::string why = rule.switch_on(c.colour, c.rule_args);
      (void)why;  // on or refused: both are answers
    }
  }
  return 0;
}
