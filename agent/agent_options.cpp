#include "agent_options.hpp"

#include <cmath>
#include <cstdlib>

#include <ev3proto/reports.hpp>

namespace ev3agent {

using ev3proto::Timer;

namespace {
/// "X,Y,HEADING" (cm, cm, degrees) as a pose in mm and degrees in [0, 360); false when it is not
/// three finite numbers, x and y within +-10 km.
bool parse_pose(const std::string& text, ev3proto::robot::Pose& out) {
  double v[3] = {};
  const char* p = text.c_str();
  for (int i = 0; i < 3; ++i) {
    char* end = nullptr;
    v[i] = std::strtod(p, &end);
    if (end == p || !std::isfinite(v[i]) || (i < 2 && std::fabs(v[i]) > 1e6)) return false;
    p = end;
    if (i < 2) {
      if (*p != ',') return false;
      ++p;
    }
  }
  if (*p != '\0') return false;
  out.x_mm = v[0] * 10.0;
  out.y_mm = v[1] * 10.0;
  const double h = std::fmod(v[2], 360.0);
  out.heading_deg = h < 0 ? h + 360.0 : h;
  return true;
}

/// A timer's default, in words for the help ("100").
std::string dflt(Timer t) { return std::to_string(ev3proto::Timers{}[t]); }

std::vector<ev3io::OptionSpec> specs() {
  std::vector<ev3io::OptionSpec> s = ev3io::common_specs();
  s.insert(s.begin() + 3, {
      {"model", "NAME", "robot model announced in AGENT (default A)", false},
      {"sysfs-root", "DIR", "ev3dev's sysfs: the devices, LEDs and battery under DIR/class (default /sys; ev3-sim's mount)", false},
      {"ports", "SPEC", "model A's ports, role=port,... (default left=outB,right=outC,touch=in1,colour=in3,ultrasonic=in4)", false},
      {"tick-ms", "N", "control tick while the motors may move, 5..100 ms (default 20)", false},
      {"watchdog-ms", "N", "wheels held this long after the last contact with a master; 0: off, else at least "
                           "2 x heartbeat (default " + std::to_string(AgentOptions{}.watchdog_ms) +
                           ", or 5 x heartbeat when that is longer)", false},
      {"heartbeat-ms", "N", "period of AGENT / PING / PANIC; the other timers but sync are multiples of it "
                            "(default " + dflt(Timer::heartbeat) + ")", false},
      {"master-timeout-ms", "N", "master silent this long: ACTIVE -> PANIC, WORKING -> PAUSED (default 8 x "
                                 "heartbeat: " + dflt(Timer::loss) + ")", false},
      {"paused-timeout-ms", "N", "master silent this long in PAUSED -> PANIC (default 10 x heartbeat: " +
                                 dflt(Timer::paused) + "; 2 x master timeout when that is given)", false},
      {"sync-timeout-ms", "N", "IDLE without MASTER this long -> PANIC (default " + dflt(Timer::sync) + ")", false},
      {"election", "", "relay and master election on (off by default: one master, the PC)", false},
      {"score", "N", "election score, lower = stands first and wins (default: from the capabilities)", false},
      {"state-dir", "DIR", "keep the election state (epoch, vote, membership, floor) in DIR/ev3-agent.state, written before "
                           "what depends on it is sent; a failed write stops the agent with status 1 (default: none, in memory only)", false},
      {"master-script", "FILE", "console commands (as ev3-master --script) run when this agent is elected master", false},
      {"report-buffer", "N", "reports kept until the PC master has recorded them, 1..1024; beyond, the oldest are "
                             "dropped and recorded as dropped (default 1024)", false},
      {"pose", "X,Y,HEADING", "where the robot starts, for its odometry: cm, cm, degrees counter-clockwise from +x "
                              "(default 0,0,0)", false},
      {"pose-ms", "N", "while it works, the robot reports its pose this often when it moved, 0..60000 ms; 0: never "
                       "(default 1000)", false},
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
        "       ev3-agent port=12233 model=A loglevel=2      (the thesis' form: key=value, '_' for '-')\n"
        "       ev3-agent --driver [--trace FILE]            (the core driven by JSON lines on stdin)\n\n"
        "One EV3 robot of the fleet: syncs with a master over UDP, answers its commands and runs\n"
        "model A's devices under --sysfs-root (a brick's /sys, or ev3-sim) with model A's behaviours\n"
        "wait, drive, explore, exploit and custom (a definition sent in BEHAVIOUR); without ev3dev's\n"
        "devices there it announces none and runs only 'wait'. The LEDs show the lifecycle, robot\n"
        "events go to the master. SIGINT/SIGTERM stop it cleanly; so does a low battery.\n"
        "With --election it relays for peers that lost the master and, when the master is gone,\n"
        "takes part in electing a new one (possibly itself: it then runs a master for the fleet).\n"
        "Exit status: 0 stopped, 1 the socket or a state write failed, 2 a bad flag or a file it cannot use.",
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
  if (a.has("ports")) {
    ev3proto::robot::ReasonText why;
    if (!ev3proto::robot::parse_ports(a.get("ports"), out.ports, why)) {
      message = "bad value for --ports: " + std::string(why.view());
      return ParseOutcome::error;
    }
  }
  {
    std::uint64_t v = out.tick_ms;
    message = ev3io::read_uint(a, "tick-ms", 5, 100, v);
    if (!message.empty()) return ParseOutcome::error;
    out.tick_ms = v;
  }
  struct {
    const char* flag;
    Timer t;
  } const rows[] = {{"heartbeat-ms", Timer::heartbeat},
                    {"master-timeout-ms", Timer::loss},
                    {"paused-timeout-ms", Timer::paused},
                    {"sync-timeout-ms", Timer::sync}};
  if (a.has("heartbeat-ms")) {  // every other timer is a multiple of it (timers.hpp), unless given
    std::uint64_t h = 0;
    message = ev3io::read_uint(a, "heartbeat-ms", 1, 86400000, h);
    if (!message.empty()) return ParseOutcome::error;
    const ev3proto::Millis sync = out.timers[Timer::sync];
    out.timers = ev3proto::Timers::for_heartbeat(h);
    out.timers.set(Timer::sync, sync);
    if (!a.has("watchdog-ms")) out.watchdog_ms = ev3proto::robot::watchdog_for(h);
  }
  for (const auto& r : rows) {
    std::uint64_t v = out.timers[r.t];
    message = ev3io::read_uint(a, r.flag, 1, 86400000, v);
    if (!message.empty()) return ParseOutcome::error;
    out.timers.set(r.t, v);
  }
  {
    std::uint64_t v = out.watchdog_ms;
    message = ev3io::read_uint(a, "watchdog-ms", 0, 600000, v);
    if (!message.empty()) return ParseOutcome::error;
    out.watchdog_ms = v;
    if (v != 0 && v < 2 * out.timers[Timer::heartbeat]) {
      message = "bad value for --watchdog-ms: " + std::to_string(v) + " (0, or at least 2 x --heartbeat-ms " +
                std::to_string(out.timers[Timer::heartbeat]) + ": a contact takes a PING and its answer)";
      return ParseOutcome::error;
    }
  }
  out.election = a.has("election");
  if (a.has("report-buffer")) {
    std::uint64_t v = 0;
    message = ev3io::read_uint(a, "report-buffer", 1, ev3proto::kReportSlots, v);
    if (!message.empty()) return ParseOutcome::error;
    out.report_buffer = static_cast<std::size_t>(v);
  }
  if (a.has("pose") && !parse_pose(a.get("pose"), out.pose)) {
    message = "bad value for --pose: '" + a.get("pose") + "' (expected X,Y,HEADING: cm, cm, degrees, e.g. 25,25,45)";
    return ParseOutcome::error;
  }
  {
    std::uint64_t v = out.pose_ms;
    message = ev3io::read_uint(a, "pose-ms", 0, 60000, v);
    if (!message.empty()) return ParseOutcome::error;
    out.pose_ms = v;
  }
  if (a.has("score")) {
    std::uint64_t v = 0;
    message = ev3io::read_uint(a, "score", 0, 1000000, v);
    if (!message.empty()) return ParseOutcome::error;
    out.score = static_cast<std::uint32_t>(v);
  }
  struct {
    const char* flag;
    std::string* to;
  } const paths[] = {{"state-dir", &out.state_dir}, {"master-script", &out.master_script}};
  for (const auto& p : paths) {
    if (!a.has(p.flag)) continue;
    *p.to = a.get(p.flag);
    if (p.to->empty()) {
      message = std::string("bad value for --") + p.flag + ": empty path";
      return ParseOutcome::error;
    }
  }
  if ((a.has("score") || a.has("state-dir") || a.has("master-script")) && !out.election) {
    message = std::string("--") + (a.has("score") ? "score" : a.has("state-dir") ? "state-dir" : "master-script") +
              " needs --election";
    return ParseOutcome::error;
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
