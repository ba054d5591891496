#include "agent_options.hpp"

namespace ev3agent {

using ev3proto::Timer;

namespace {
std::vector<ev3io::OptionSpec> specs() {
  std::vector<ev3io::OptionSpec> s = ev3io::common_specs();
  s.insert(s.begin() + 3, {
      {"model", "NAME", "robot model announced in AGENT (default A)", false},
      {"sysfs-root", "DIR", "where ev3dev's class/leds (and devices) are (default /sys)", false},
      {"heartbeat-ms", "N", "period of AGENT / PING / PANIC (default 1000)", false},
      {"master-timeout-ms", "N", "master silent this long: ACTIVE -> PANIC, WORKING -> PAUSED (default 3000)", false},
      {"paused-timeout-ms", "N", "master silent this long in PAUSED -> PANIC (default 2 x master timeout)", false},
      {"sync-timeout-ms", "N", "IDLE without MASTER this long -> PANIC (default 10000)", false},
  });
  return s;
}
}  // namespace

ParseOutcome parse_agent_options(int argc, const char* const* argv, AgentOptions& out, std::string& message) {
  const auto sp = specs();
  ev3io::ParsedArgs a;
  message = ev3io::parse_args(argc, argv, sp, "agent", a);
  if (!message.empty()) return ParseOutcome::error;
  if (a.help) {
    message = ev3io::usage(
        "usage: ev3-agent [--port N] [--model NAME] [--broadcast HOST:PORT ...] [options]\n"
        "       ev3-agent port=12233 model=A loglevel=2      (the thesis' form)\n\n"
        "One EV3 robot of the fleet: syncs with a master over UDP, answers its commands and runs\n"
        "the built-in behaviour 'wait seconds=N'. SIGINT/SIGTERM stop it cleanly.",
        sp);
    return ParseOutcome::help;
  }
  message = ev3io::read_common(a, out.common);
  if (!message.empty()) return ParseOutcome::error;
  if (a.has("model")) {
    out.model = a.get("model");
    if (out.model.empty() || out.model.size() > 32 ||
        out.model.find_first_of(": %") != std::string::npos) {
      message = "bad value for --model: '" + out.model + "' (expected a short name without ':', '%' or spaces)";
      return ParseOutcome::error;
    }
  }
  if (a.has("sysfs-root")) {
    out.sysfs_root = a.get("sysfs-root");
    if (out.sysfs_root.empty()) {
      message = "bad value for --sysfs-root: empty path";
      return ParseOutcome::error;
    }
  }
  struct {
    const char* flag;
    Timer t;
  } const rows[] = {{"heartbeat-ms", Timer::heartbeat},
                    {"master-timeout-ms", Timer::loss},
                    {"paused-timeout-ms", Timer::paused},
                    {"sync-timeout-ms", Timer::sync}};
  for (const auto& r : rows) {
    std::uint64_t v = out.timers[r.t];
    message = ev3io::read_uint(a, r.flag, 1, 86400000, v);
    if (!message.empty()) return ParseOutcome::error;
    out.timers.set(r.t, v);
  }
  if (a.has("master-timeout-ms") && !a.has("paused-timeout-ms"))
    out.timers.set(Timer::paused, 2 * out.timers[Timer::loss]);
  if (!out.timers.valid()) {
    message = "bad value for --paused-timeout-ms: " + std::to_string(out.timers[Timer::paused]) +
              " (must be greater than --master-timeout-ms " + std::to_string(out.timers[Timer::loss]) + ")";
    return ParseOutcome::error;
  }
  return ParseOutcome::run;
}

}  // namespace ev3agent
