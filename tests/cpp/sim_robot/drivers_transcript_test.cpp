// The driver emulation, as transcripts (testdata/*.txt, etcd datadriven style). Each case runs on
// a fresh robot (model A, stretch names unless the first line is `jessie`) in an empty 4 m x 4 m
// world (a red floor patch at 0..50, 0..50 and a black one at 350..400, 350..400), facing +x
// from (100, 200). Input lines:
//
//   write DEV ATTR VALUE   write VALUE to DEV's attribute: prints "DEV/ATTR <- VALUE: ok" or the
//                          errno name; "(answers after N ms)" when the write takes simulated time
//   read DEV ATTR          prints "DEV/ATTR: VALUE" (newline shown as nothing) or the errno name
//   run MS                 advances the simulation by MS milliseconds (prints nothing)
//   ctl COMMAND...         a control command: prints "ctl: ok" or "ctl: error: ..."
//   ls DEV                 prints the class directory of DEV ("gone" when there is none)
//   pose                   prints the robot's position (cm, 1 decimal) and heading (degrees)
//   jessie                 (first line only) jessie names
//
// DEV is a port (outB, in4, ...), `battery`, or an LED name. An attribute is looked up through
// the class directory each time, unless the device was unplugged: then the last node found is
// used, as a descriptor opened before the unplug would be.
#include <gtest/gtest.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>

#include "datadriven/datadriven.hpp"
#include "ev3sim/sim.hpp"

namespace {

using namespace ev3sim;

std::string errno_name(int e) {
  switch (e) {
    case EINVAL: return "EINVAL";
    case EBUSY: return "EBUSY";
    case ENODEV: return "ENODEV";
    case ENXIO: return "ENXIO";
    case EACCES: return "EACCES";
    case ENOENT: return "ENOENT";
    case ERANGE: return "ERANGE";
    case EIO: return "EIO";
    case ETIMEDOUT: return "ETIMEDOUT";
    case EOPNOTSUPP: return "EOPNOTSUPP";
    default: return "errno " + std::to_string(e);
  }
}

std::vector<std::string> words(const std::string& line) {
  std::vector<std::string> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && line[i] == ' ') ++i;
    std::size_t j = line.find(' ', i);
    if (j == std::string::npos) j = line.size();
    if (j > i) out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

class Harness {
 public:
  explicit Harness(Generation gen) {
    World w;
    std::string err = parse_world("bounds 0 0 400 400\nfloor red rect 0 0 50 50\nfloor black rect 350 350 50 50 reflect 4\n", "transcript", w);
    EXPECT_EQ(err, "");
    sim_ = std::make_unique<Sim>(w);
    RobotConfig cfg;
    cfg.gen = gen;
    cfg.start.p = {100, 200};
    EXPECT_EQ(sim_->add_robot(cfg), "");
    robot_ = sim_->robots().front().get();
  }

  std::string dir_of(const std::string& dev) {
    if (dev == "battery")
      return robot_->config().gen == Generation::Stretch ? "class/power_supply/lego-ev3-battery"
                                                         : "class/power_supply/legoev3-battery";
    if (port_index(dev) >= 0) return robot_->class_path(dev);
    return "class/leds/" + dev;
  }

  Ino node(const std::string& dev, const std::string& attr) {
    const std::string key = dev + "/" + attr;
    const std::string dir = dir_of(dev);
    if (!dir.empty()) {
      // Follow the class symlink as the kernel would, then the attribute.
      const Ino link = robot_->tree().resolve(dir);
      if (link) {
        const Node* l = robot_->tree().node(link);
        const std::string target = l->kind == NodeKind::Link ? resolve_link(dir, l->target) : dir;
        if (Ino n = robot_->tree().resolve(target + "/" + attr)) held_[key] = n;
        else held_.erase(key);
      }
    }
    auto it = held_.find(key);
    return it == held_.end() ? 0 : it->second;
  }

  static std::string resolve_link(const std::string& link_path, const std::string& target) {
    std::vector<std::string> parts;
    std::string base = link_path.substr(0, link_path.rfind('/'));
    for (const std::string& p : split(base)) parts.push_back(p);
    for (const std::string& p : split(target)) {
      if (p == "..") parts.pop_back();
      else parts.push_back(p);
    }
    std::string out;
    for (const std::string& p : parts) out += (out.empty() ? "" : "/") + p;
    return out;
  }

  static std::vector<std::string> split(const std::string& s) {
    std::vector<std::string> out;
    std::size_t i = 0;
    while (i <= s.size()) {
      std::size_t j = s.find('/', i);
      if (j == std::string::npos) j = s.size();
      if (j > i) out.push_back(s.substr(i, j - i));
      i = j + 1;
    }
    return out;
  }

  std::vector<std::string> run(const std::vector<std::string>& input) {
    std::vector<std::string> out;
    for (const std::string& line : input) {
      const auto w = words(line);
      if (w.empty()) continue;
      robot_->set_now(sim_->now());
      if (w[0] == "write" && w.size() >= 3) {
        const std::string value = w.size() > 3 ? line.substr(line.find(w[3], line.find(w[2]) + w[2].size())) : "";
        const Ino n = node(w[1], w[2]);
        const WriteResult r = n ? robot_->tree().write(n, value + "\n") : WriteResult{ENOENT, 0};
        std::string s = w[1] + "/" + w[2] + " <- " + value + ": " + (r.err ? errno_name(r.err) : "ok");
        if (r.done_at > sim_->now())
          s += " (answers after " + std::to_string((r.done_at - sim_->now()) / 1000) + " ms)";
        out.push_back(s);
      } else if (w[0] == "read" && w.size() == 3) {
        const Ino n = node(w[1], w[2]);
        const ReadResult r = n ? robot_->tree().read(n) : ReadResult{ENOENT, {}};
        std::string v = r.data;
        while (!v.empty() && v.back() == '\n') v.pop_back();
        out.push_back(w[1] + "/" + w[2] + ": " + (r.err ? errno_name(r.err) : v));
      } else if (w[0] == "run" && w.size() == 2) {
        sim_->advance_to(sim_->now() + std::stoll(w[1]) * 1000);
      } else if (w[0] == "ctl") {
        const ControlResult r = sim_->control(line.substr(4));
        out.push_back(r.ok ? "ctl: ok" : "ctl: error: " + r.message);
      } else if (w[0] == "ls" && w.size() == 2) {
        const std::string d = dir_of(w[1]);
        out.push_back(w[1] + ": " + (d.empty() ? "gone" : d));
      } else if (w[0] == "pose") {
        char buf[96];
        std::snprintf(buf, sizeof buf, "pose: %.1f %.1f %.1f", robot_->pose().p.x, robot_->pose().p.y,
                      rad2deg(robot_->pose().heading));
        out.push_back(buf);
      } else {
        out.push_back("bad input line: " + line);
      }
    }
    return out;
  }

 private:
  std::unique_ptr<Sim> sim_;
  Robot* robot_ = nullptr;
  std::map<std::string, Ino> held_;
};

void run_file(const std::string& name) {
  const std::string path = std::string(EV3_SIM_TESTDATA) + "/" + name;
  std::string error;
  const datadriven::File f = datadriven::parse(path, error);
  ASSERT_EQ(error, "");
  ASSERT_FALSE(f.cases.empty()) << path;
  std::vector<std::vector<std::string>> actual;
  for (const datadriven::Case& c : f.cases) {
    std::vector<std::string> input = c.input;
    Generation gen = Generation::Stretch;
    if (!input.empty() && input.front() == "jessie") {
      gen = Generation::Jessie;
      input.erase(input.begin());
    }
    Harness h(gen);
    actual.push_back(h.run(input));
    if (!datadriven::rewriting()) {
      std::string want, got;
      for (const auto& l : c.expected) want += l + "\n";
      for (const auto& l : actual.back()) got += l + "\n";
      EXPECT_EQ(want, got) << c.file << ":" << c.line;
    }
  }
  if (datadriven::rewriting()) {
    ASSERT_TRUE(datadriven::rewrite(path, f, actual));
  }
}

TEST(DriverTranscripts, TachoMotor) { run_file("tacho_motor.txt"); }
TEST(DriverTranscripts, Sensors) { run_file("sensors.txt"); }
TEST(DriverTranscripts, PlugAndFaults) { run_file("plug_faults.txt"); }
TEST(DriverTranscripts, LedsAndBattery) { run_file("leds_battery.txt"); }

}  // namespace
