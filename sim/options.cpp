#include "ev3sim/options.hpp"

#include "ev3io/cli.hpp"
#include "ev3sim/sim.hpp"

namespace ev3sim {

namespace {

std::vector<ev3io::OptionSpec> specs() {
  return {
      {"world", "FILE", "the world file (docs/devices.md, \"World files\")", false},
      {"sysfs-root", "DIR", "mount a robot's ev3dev tree on DIR (one per robot)", true},
      {"robot", "X,Y,HEADING", "the robot's start pose in cm and degrees (else the world's start line)", true},
      {"name", "NAME", "the robot's name in control commands and pictures (default robot1, robot2, ...)", true},
      {"rate", "HZ", "how often the clock advances, 100..10000 (default 100; physics steps are 1 ms)", false},
      {"time-scale", "K", "simulated seconds per real second, 0.01..1000 (default 1; tests speed up)", false},
      {"jessie", "", "jessie names (outB, ev3:left:green:ev3dev, legoev3-battery) instead of stretch", false},
      {"snapshot", "FILE.svg", "picture of the world and the paths, at exit and on SIGUSR1", false},
      {"control", "FIFO", "read control commands (faults) from FIFO, created if missing", false},
      {"status", "FILE", "JSON state of the robots, at exit and on SIGUSR1", false},
      {"duration", "S", "stop after S simulated seconds (default: run until SIGINT/SIGTERM)", false},
      {"battery-volts", "V", "battery open-circuit voltage at start, 5..10 (default 8.04)", false},
      {"battery-mah", "N", "battery capacity, 1..100000 mAh (default 2000; small drains fast)", false},
      {"seed", "N", "seed of the garbage-values fault (default 1)", false},
      {"allow-other", "", "let other users use the mounts (FUSE allow_other)", false},
      {"log-level", "0..4", "0 none, 1 error, 2 info (default), 3 debug, 4 verbose", false},
      {"log-file", "PATH", "log to PATH (appending) instead of stderr", false},
  };
}

std::string bad(const std::string& flag, const std::string& value, const std::string& expected) {
  return "bad value for --" + flag + ": '" + value + "' (expected " + expected + ")";
}

}  // namespace

std::string sim_usage() {
  return ev3io::usage(
      "usage: ev3-sim --world FILE --sysfs-root DIR [--robot X,Y,HEADING] [--name NAME]\n"
      "               [--sysfs-root DIR2 [--robot ...] [--name ...]]... [options]\n\n"
      "Serves the ev3dev sysfs tree of model A under each DIR (FUSE) and drives the robots in the\n"
      "world: motors, sensors, LEDs, battery, collisions. The i-th --robot and --name go with the\n"
      "i-th --sysfs-root. Control commands (FIFO): unplug|replug [ROBOT] PORT, plug [ROBOT] PORT\n"
      "DRIVER, battery [ROBOT] VOLTS, garbage [ROBOT] PORT on|off, place [ROBOT] X Y HEADING,\n"
      "snapshot [FILE], status [FILE], quit. Exit status: 0, 1 on a runtime error (no /dev/fuse,\n"
      "a mount failing), 2 on bad arguments or a bad world file.",
      specs());
}

std::string parse_sim_options(int argc, const char* const* argv, SimOptions& out) {
  ev3io::ParsedArgs a;
  if (std::string e = ev3io::parse_args(argc, argv, specs(), "", a); !e.empty()) return e;
  out.help = a.help;
  if (a.help) return {};
  if (!a.has("world") || a.get("world").empty()) return "missing --world FILE";
  out.world = a.get("world");
  if (!a.has("sysfs-root")) return "missing --sysfs-root DIR (where the robot's tree is mounted)";
  const auto& roots = a.values.at("sysfs-root");
  const std::vector<std::string> none;
  const auto& poses = a.has("robot") ? a.values.at("robot") : none;
  const auto& names = a.has("name") ? a.values.at("name") : none;
  if (poses.size() > roots.size()) return "more --robot than --sysfs-root (one --robot per robot)";
  if (names.size() > roots.size()) return "more --name than --sysfs-root (one --name per robot)";
  for (std::size_t i = 0; i < roots.size(); ++i) {
    RobotOptions r;
    r.root = roots[i];
    if (r.root.empty()) return "bad value for --sysfs-root: empty path";
    for (std::size_t j = 0; j < i; ++j)
      if (out.robots[j].root == r.root) return "two robots share --sysfs-root " + r.root;
    r.name = i < names.size() ? names[i] : "robot" + std::to_string(i + 1);
    if (r.name.empty() || r.name.find_first_of(" \t\n") != std::string::npos)
      return bad("name", r.name, "a word");
    for (std::size_t j = 0; j < i; ++j)
      if (out.robots[j].name == r.name) return "two robots are called " + r.name;
    if (i < poses.size()) {
      Pose p;
      if (!parse_pose(poses[i], p)) return bad("robot", poses[i], "X,Y,HEADING in cm, cm, degrees, e.g. 30,40,90");
      r.pose = p;
    }
    out.robots.push_back(std::move(r));
  }
  auto number = [&a](const char* flag, double lo, double hi, double& v, const char* what) -> std::string {
    if (!a.has(flag)) return {};
    const std::string s = a.get(flag);
    if (!ev3io::to_double(s, lo, hi, v)) return bad(flag, s, what);
    return {};
  };
  std::string e;
  if (!(e = number("rate", 100, 10000, out.rate_hz, "a rate of 100..10000 Hz")).empty()) return e;
  if (!(e = number("time-scale", 0.01, 1000, out.time_scale, "a factor 0.01..1000")).empty()) return e;
  if (!(e = number("duration", 0, 1e7, out.duration_s, "seconds of simulated time")).empty()) return e;
  if (!(e = number("battery-volts", 5, 10, out.battery_volts, "volts 5..10")).empty()) return e;
  if (!(e = number("battery-mah", 1, 100000, out.battery_mah, "1..100000 mAh")).empty()) return e;
  std::uint64_t u = out.seed;
  if (!(e = ev3io::read_uint(a, "seed", 0, UINT64_MAX / 10, u)).empty()) return e;
  out.seed = u;
  u = static_cast<std::uint64_t>(out.log_level);
  if (!(e = ev3io::read_uint(a, "log-level", 0, 4, u)).empty()) return e;
  out.log_level = static_cast<int>(u);
  out.gen = a.has("jessie") ? Generation::Jessie : Generation::Stretch;
  out.allow_other = a.has("allow-other");
  for (auto [flag, dst] : {std::pair{"snapshot", &out.snapshot}, std::pair{"control", &out.control},
                           std::pair{"status", &out.status}, std::pair{"log-file", &out.log_file}}) {
    if (!a.has(flag)) continue;
    *dst = a.get(flag);
    if (dst->empty()) return std::string("bad value for --") + flag + ": empty path";
  }
  return {};
}

}  // namespace ev3sim
