#include "ev3sim/options.hpp"

#include <sstream>

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
      "a mount failing), 2 on bad arguments or a bad world file.\n\n"
      "ev3-sim exec (--robot N|NAME | --sysfs-root DIR) -- COMMAND [ARGS]... runs a program written\n"
      "for a brick with a running ev3-sim's robot tree as /sys/class (ev3-sim exec --help).\n"
      "ev3-sim world FILE checks a world file and prints it as JSON.",
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

// --- ev3-sim exec ------------------------------------------------------------------------------

std::string exec_usage() {
  return "usage: ev3-sim exec (--robot N|NAME | --sysfs-root DIR) -- COMMAND [ARGS]...\n\n"
         "Runs COMMAND with the tree of one robot of a running ev3-sim in place of /sys/class and\n"
         "/sys/devices, in a private mount namespace (needs root): a program written for a brick\n"
         "(python-ev3dev2, ev3dev-lang-cpp) drives the simulated robot unmodified.\n\n"
         "  --robot N|NAME     the N-th robot of the running ev3-sim (its N-th --sysfs-root), or the\n"
         "                     robot called NAME\n"
         "  --sysfs-root DIR   the robot whose tree ev3-sim mounts on DIR (when several ev3-sim run)\n\n"
         "Exit status: COMMAND's; 1 when no running ev3-sim serves that robot or the namespace\n"
         "cannot be made (not root); 2 on bad arguments; 127 when COMMAND is not found.\n";
}

std::string parse_exec_options(int argc, const char* const* argv, ExecOptions& out) {
  int i = 1;
  for (; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--") {
      ++i;
      break;
    }
    if (a == "--help" || a == "-h") {
      out.help = true;
      return {};
    }
    std::string* dst = a == "--robot" ? &out.robot : a == "--sysfs-root" ? &out.root : nullptr;
    if (!dst) return "exec: unknown argument '" + a + "' (the command comes after --)";
    if (i + 1 >= argc || std::string(argv[i + 1]).empty()) return "exec: " + a + " needs a value";
    if (!dst->empty()) return "exec: " + a + " given twice";
    *dst = argv[++i];
  }
  for (; i < argc; ++i) out.command.emplace_back(argv[i]);
  if (out.robot.empty() && out.root.empty()) return "exec: name the robot: --robot N|NAME or --sysfs-root DIR";
  if (out.command.empty()) return "exec: no command (give it after --)";
  return {};
}

std::string mount_source(std::size_t index, const std::string& name) {
  return "ev3-sim:" + std::to_string(index) + ":" + name;
}

namespace {

// mountinfo writes space, tab, newline and backslash as \ooo (octal).
std::string unescape_mountinfo(const std::string& s) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '\\' && i + 3 < s.size() && s[i + 1] >= '0' && s[i + 1] <= '3' && s[i + 2] >= '0' &&
        s[i + 2] <= '7' && s[i + 3] >= '0' && s[i + 3] <= '7') {
      out += static_cast<char>((s[i + 1] - '0') * 64 + (s[i + 2] - '0') * 8 + (s[i + 3] - '0'));
      i += 3;
    } else {
      out += s[i];
    }
  }
  return out;
}

bool all_digits(const std::string& s) {
  return !s.empty() && s.size() < 10 && s.find_first_not_of("0123456789") == std::string::npos;
}

std::string describe(const SimMount& m) {
  return m.name + " (robot " + std::to_string(m.index) + ") on " + m.dir;
}

}  // namespace

std::vector<SimMount> parse_sim_mounts(const std::string& mountinfo) {
  // A line: id parent major:minor root mountpoint options [optional fields...] - fstype source superopts
  std::vector<SimMount> out;
  std::istringstream lines(mountinfo);
  std::string line;
  while (std::getline(lines, line)) {
    std::istringstream f(line);
    std::vector<std::string> w;
    for (std::string t; f >> t;) w.push_back(t);
    std::size_t dash = 6;
    while (dash < w.size() && w[dash] != "-") ++dash;
    if (w.size() < 5 || dash + 2 >= w.size() || w[dash + 1] != "fuse.ev3-sim") continue;
    const std::string source = unescape_mountinfo(w[dash + 2]);
    const std::string prefix = "ev3-sim:";
    if (source.compare(0, prefix.size(), prefix) != 0) continue;
    const std::size_t colon = source.find(':', prefix.size());
    if (colon == std::string::npos) continue;
    const std::string index = source.substr(prefix.size(), colon - prefix.size());
    if (!all_digits(index)) continue;
    out.push_back({unescape_mountinfo(w[4]), std::stol(index), source.substr(colon + 1)});
  }
  return out;
}

std::string pick_sim_mount(const std::vector<SimMount>& mounts, const ExecOptions& opt,
                           const std::string& real_root, SimMount& out) {
  if (mounts.empty()) return "exec: no ev3-sim is running (no fuse.ev3-sim mount in /proc/self/mountinfo)";
  std::vector<SimMount> found;
  for (const SimMount& m : mounts) {
    if (!real_root.empty() && m.dir != real_root) continue;
    if (!opt.robot.empty() && !(all_digits(opt.robot) ? std::stol(opt.robot) == m.index : opt.robot == m.name))
      continue;
    found.push_back(m);
  }
  std::string running;
  for (const SimMount& m : mounts) running += (running.empty() ? "" : ", ") + describe(m);
  if (found.empty()) {
    std::string what = !opt.root.empty() ? "serves a tree on " + opt.root : "serves robot " + opt.robot;
    if (!opt.root.empty() && !opt.robot.empty()) what += " for robot " + opt.robot;
    return "exec: no running ev3-sim " + what + " (running: " + running + ")";
  }
  if (found.size() > 1) {
    std::string which;
    for (const SimMount& m : found) which += (which.empty() ? "" : ", ") + describe(m);
    return "exec: robot " + opt.robot + " is ambiguous: " + which + "; name its tree with --sysfs-root DIR";
  }
  out = found.front();
  return {};
}

}  // namespace ev3sim
