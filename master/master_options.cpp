#include "master_options.hpp"

namespace ev3master {

using ev3proto::Timer;

ParseOutcome parse_master_options(int argc, const char* const* argv, MasterOptions& out, std::string& message) {
  std::vector<ev3io::OptionSpec> sp = ev3io::common_specs();
  sp.insert(sp.begin() + 3, {
      {"agent-timeout-ms", "N", "an agent not heard this long is lost and leaves the registry (default " +
                                std::to_string(ev3proto::Timers{}[Timer::drop]) + ")", false},
      {"resend-ms", "N", "resend an unanswered command after N ms (default " +
                         std::to_string(ev3proto::Timers{}[Timer::resend]) + ")", false},
      {"max-resends", "N", "a command unanswered after N resends times out (default 10)", false},
      {"status-json", "FILE", "write the fleet's state to FILE (atomically, twice a second)", false},
      {"script", "FILE", "console commands to run (with 'wait SECONDS' between them)", false},
      {"election", "", "relay and election on: LEADER heartbeats, epochs; agents may elect a new master", false},
      {"state-file", "FILE", "keep next id, msgids, epoch and members in FILE; restarted with it, the master "
                             "continues them and (with --election) stands to take the fleet back (default: none)", false},
      {"record", "FILE", "append every report the agents number to FILE before acknowledging it; restarted "
                         "with it, the master continues each agent's record (default: none)", false},
      {"control", "PATH", "take console commands on a Unix socket at PATH, one per line, one answer per line "
                          "(mode 0600; default: none)", false},
      {"control-group", "GROUP", "the control socket 0660, owned by group GROUP", false},
      {"json", "", "answer on the control socket in JSON (else a line asks for it: --json COMMAND)", false},
      {"db", "FILE", "keep robots, state changes, commands and answers, reports and epochs in the SQLite "
                     "database FILE (created, or continued; needs --state-file)", false},
  });
  ev3io::ParsedArgs a;
  message = ev3io::parse_args(argc, argv, sp, "master", a);
  if (!message.empty()) return ParseOutcome::error;
  if (a.help) {
    message = ev3io::usage(
        "usage: ev3-master [--port N] [--broadcast HOST:PORT ...] [--status-json FILE] [--script FILE] [options]\n\n"
        "The fleet's master: registers agents over UDP, answers their PINGs, sends the operator's\n"
        "commands. On a terminal: a live table and a prompt (commands: list, behaviour ID NAME\n"
        "[key=value ...], start|stop|pause|resume|standby|continue|restart ID|all, quit).",
        sp);
    return ParseOutcome::help;
  }
  message = ev3io::read_common(a, out.common);
  if (!message.empty()) return ParseOutcome::error;
  std::uint64_t v = out.timers[Timer::drop];
  message = ev3io::read_uint(a, "agent-timeout-ms", 1, 86400000, v);
  if (!message.empty()) return ParseOutcome::error;
  out.timers.set(Timer::drop, v);
  v = out.timers[Timer::resend];
  message = ev3io::read_uint(a, "resend-ms", 1, 600000, v);
  if (!message.empty()) return ParseOutcome::error;
  out.timers.set(Timer::resend, v);
  v = out.max_resends;
  message = ev3io::read_uint(a, "max-resends", 0, 1000000, v);
  if (!message.empty()) return ParseOutcome::error;
  out.max_resends = static_cast<std::uint32_t>(v);
  out.status_json = a.get("status-json");
  if (a.has("status-json") && out.status_json.empty()) {
    message = "bad value for --status-json: empty path";
    return ParseOutcome::error;
  }
  out.script = a.get("script");
  if (a.has("script") && out.script.empty()) {
    message = "bad value for --script: empty path";
    return ParseOutcome::error;
  }
  out.election = a.has("election");
  out.state_file = a.get("state-file");
  if (a.has("state-file") && out.state_file.empty()) {
    message = "bad value for --state-file: empty path";
    return ParseOutcome::error;
  }
  out.record = a.get("record");
  if (a.has("record") && out.record.empty()) {
    message = "bad value for --record: empty path";
    return ParseOutcome::error;
  }
  out.control = a.get("control");
  if (a.has("control") && out.control.empty()) {
    message = "bad value for --control: empty path";
    return ParseOutcome::error;
  }
  out.control_group = a.get("control-group");
  if (a.has("control-group") && (out.control_group.empty() || out.control.empty())) {
    message = out.control.empty() ? "--control-group needs --control" : "bad value for --control-group: empty name";
    return ParseOutcome::error;
  }
  out.db = a.get("db");
  if (a.has("db") && (out.db.empty() || out.state_file.empty())) {
    message = out.db.empty() ? "bad value for --db: empty path"
                             : "--db needs --state-file (the record names robots by id: ids must never be handed out twice)";
    return ParseOutcome::error;
  }
  out.json = a.has("json");
  if (out.json && out.control.empty()) {
    message = "--json needs --control (it is how the control socket answers)";
    return ParseOutcome::error;
  }
  return ParseOutcome::run;
}

}  // namespace ev3master
