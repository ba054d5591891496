// The device layer (io/ev3io/devices.hpp, sysfs.hpp, robot_io.hpp) on copies of the reference
// trees of real bricks (tests/data/ev3dev/{stretch,jessie}) as plain files: discovery by address
// and driver name in both generations, values, writes, garbage, unplug by removing the device,
// replug under a new index; and, through the fault seam (SysfsIo), what plain files cannot do:
// ENODEV after an unplug, EBUSY from `position`, a stale LED attribute. Last, the robot runtime
// driven through the layer on a tree, as the agent program will.
#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include "ev3io/devices.hpp"
#include "ev3io/robot_io.hpp"
#include "fault_io.hpp"

namespace {

namespace fs = std::filesystem;
using ev3io::Access;
using ev3io::DeviceChange;
using ev3io::Ev3Devices;
using ev3test::FaultIo;
using namespace ev3proto::robot;

/// A copy of a reference tree in a fresh temporary directory (removed at the end).
class Tree {
 public:
  explicit Tree(const std::string& generation) {
    char tmpl[] = "/tmp/ev3dev-tree-XXXXXX";
    root_ = mkdtemp(tmpl);
    fs::copy(std::string(EV3_TREES) + "/" + generation, root_,
             fs::copy_options::recursive | fs::copy_options::copy_symlinks);
  }
  ~Tree() { fs::remove_all(root_); }
  const std::string& root() const { return root_; }
  /// The directory a class entry links to ("class/tacho-motor/motor1").
  std::string target(const std::string& entry) const {
    return fs::canonical(root_ + "/" + entry).string();
  }
  std::string read(const std::string& path) const {
    std::ifstream in(path);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }
  void write(const std::string& path, const std::string& text) const { std::ofstream(path, std::ios::trunc) << text; }
  /// Unplugs: the class link and the device directory disappear (as sysfs removes them).
  std::string unplug(const std::string& entry) const {
    const std::string dir = target(entry);
    const std::string saved = dir + ".saved";
    fs::rename(dir, saved);
    fs::remove(root_ + "/" + entry);
    return saved;
  }
  /// Plugs a device back from @p saved as class entry @p entry (a new index).
  void replug(const std::string& saved, const std::string& entry) const {
    const std::string dir = saved.substr(0, saved.size() - 6);
    const std::string new_dir = dir.substr(0, dir.rfind('/') + 1) + entry.substr(entry.rfind('/') + 1);
    fs::rename(saved, new_dir);
    fs::create_symlink(fs::relative(new_dir, fs::path(root_ + "/" + entry).parent_path()), root_ + "/" + entry);
  }

 private:
  std::string root_;
};

std::map<Dev, DeviceChange> by_port(const std::vector<DeviceChange>& v) {
  std::map<Dev, DeviceChange> m;
  for (const auto& c : v) m[c.info.dev] = c;
  return m;
}

class Generations : public ::testing::TestWithParam<std::string> {};

TEST_P(Generations, FindsModelAByAddressAndDriver) {
  Tree t(GetParam());
  Ev3Devices d(t.root());
  std::vector<DeviceChange> ch;
  d.scan(ch);
  ASSERT_EQ(ch.size(), 5u);
  const auto m = by_port(ch);
  for (Dev p : {Dev::outB, Dev::outC, Dev::in1, Dev::in3, Dev::in4}) {
    ASSERT_EQ(m.count(p), 1u) << to_string(p);
    EXPECT_EQ(m.at(p).kind, DeviceChange::Kind::connected) << m.at(p).why;
  }
  EXPECT_EQ(m.at(Dev::outB).info.driver, Driver::ev3_large_motor);
  EXPECT_EQ(m.at(Dev::outB).info.motor.max_speed, 1050);
  EXPECT_EQ(m.at(Dev::outC).info.motor.count_per_rot, 360);
  EXPECT_EQ(m.at(Dev::outB).info.motor.stop_actions, bit(StopAction::coast) | bit(StopAction::brake) | bit(StopAction::hold));
  EXPECT_EQ(m.at(Dev::in1).info.driver, Driver::ev3_touch);
  EXPECT_EQ(m.at(Dev::in3).info.driver, Driver::ev3_color);
  EXPECT_EQ(m.at(Dev::in3).info.sensor.mode_name(), "COL-REFLECT");
  EXPECT_EQ(m.at(Dev::in4).info.sensor.mode_name(), "US-DIST-CM");
  EXPECT_EQ(m.at(Dev::in4).info.sensor.decimals, 1);
  EXPECT_EQ(m.at(Dev::in4).info.sensor.mode_count, 7);
  EXPECT_EQ(std::string(d.led_names()), GetParam());
  for (std::size_t i = 0; i < 4; ++i) EXPECT_EQ(d.led_max(led_dev(i)), 255);
  EXPECT_TRUE(d.has_battery());
  EXPECT_TRUE(d.ignored().empty());
  // Values: the ultrasonic's 2550 is 255.0 cm (decimals 1); the battery in µV.
  auto r = d.read(Dev::in4, Attr::value0);
  ASSERT_EQ(r.status, Access::ok);
  std::int32_t v = 0;
  EXPECT_TRUE(parse_int(r.text, v));
  EXPECT_EQ(v, 2550);
  r = d.read(Dev::battery, Attr::voltage_now);
  ASSERT_EQ(r.status, Access::ok);
  EXPECT_TRUE(parse_int(r.text, v));
  EXPECT_GT(v, 5000000);
  // A second scan finds nothing new.
  d.scan(ch);
  EXPECT_TRUE(ch.empty());
}

TEST_P(Generations, WritesLandInTheFiles) {
  Tree t(GetParam());
  Ev3Devices d(t.root());
  std::vector<DeviceChange> ch;
  d.scan(ch);
  const std::string motor = d.dir(Dev::outB);
  ASSERT_EQ(d.write(Dev::outB, Attr::speed_sp, "500").status, Access::ok);
  ASSERT_EQ(d.write(Dev::outB, Attr::command, "run-forever").status, Access::ok);
  EXPECT_EQ(t.read(motor + "/speed_sp"), "500");
  EXPECT_EQ(t.read(motor + "/command"), "run-forever");
  ASSERT_EQ(d.write(Dev::outB, Attr::speed_sp, "5").status, Access::ok);  // shorter: no old bytes left
  EXPECT_EQ(t.read(motor + "/speed_sp"), "5");
  // LEDs: delay_on / delay_off exist only while the trigger is timer: created in a plain tree.
  const Dev led = Dev::led_left_red;
  for (auto [a, v] : std::vector<std::pair<Attr, const char*>>{{Attr::trigger, "timer"}, {Attr::delay_on, "500"},
                                                                 {Attr::delay_off, "500"}, {Attr::brightness, "26"}})
    ASSERT_EQ(d.write(led, a, v).status, Access::ok) << to_string(a);
  const std::string led_dir = t.root() + "/class/leds/" + (GetParam() == "stretch" ? "led0:red:brick-status" : "ev3:left:red:ev3dev");
  EXPECT_EQ(t.read(led_dir + "/brightness"), "26");
  EXPECT_EQ(t.read(led_dir + "/delay_on"), "500");
}

TEST_P(Generations, UnplugAndReplugUnderANewIndex) {
  Tree t(GetParam());
  Ev3Devices d(t.root());
  std::vector<DeviceChange> ch;
  d.scan(ch);
  const std::string saved = t.unplug("class/tacho-motor/motor1");
  d.scan(ch);
  ASSERT_EQ(ch.size(), 1u);
  EXPECT_EQ(ch[0].kind, DeviceChange::Kind::disconnected);
  EXPECT_EQ(ch[0].info.dev, Dev::outC);
  EXPECT_FALSE(d.present(Dev::outC));
  EXPECT_EQ(d.read(Dev::outC, Attr::position).status, Access::gone);
  d.scan(ch);
  EXPECT_TRUE(ch.empty());
  t.replug(saved, "class/tacho-motor/motor7");
  t.write(t.root() + "/class/tacho-motor/motor7/position", "42\n");
  d.scan(ch);
  ASSERT_EQ(ch.size(), 1u);
  EXPECT_EQ(ch[0].kind, DeviceChange::Kind::connected);
  EXPECT_EQ(ch[0].info.dev, Dev::outC);
  EXPECT_NE(ch[0].dir.find("motor7"), std::string::npos);
  const auto r = d.read(Dev::outC, Attr::position);  // the new device's files
  ASSERT_EQ(r.status, Access::ok);
  EXPECT_EQ(r.text, "42\n");
  // A sensor moved to another port under the same index: gone from in3, there on in2.
  t.write(t.root() + "/class/lego-sensor/sensor1/address", GetParam() == "stretch" ? "ev3-ports:in2\n" : "in2\n");
  d.scan(ch);
  ASSERT_EQ(ch.size(), 2u);
  EXPECT_EQ(ch[0].kind, DeviceChange::Kind::disconnected);
  EXPECT_EQ(ch[0].info.dev, Dev::in3);
  EXPECT_EQ(ch[1].kind, DeviceChange::Kind::connected);
  EXPECT_EQ(ch[1].info.dev, Dev::in2);
}

TEST_P(Generations, GarbageIsAClearErrorNotACrash) {
  Tree t(GetParam());
  t.write(t.root() + "/class/tacho-motor/motor0/max_speed", "fast\n");
  t.write(t.root() + "/class/lego-sensor/sensor0/modes", "\n");
  t.write(t.root() + "/class/lego-sensor/sensor2/decimals", "-1\n");
  t.write(t.root() + "/class/tacho-motor/motor1/address", "ev3-ports:outZ\n");
  Ev3Devices d(t.root());
  std::vector<DeviceChange> ch;
  d.scan(ch);
  const auto m = by_port(ch);
  ASSERT_EQ(m.count(Dev::outB), 1u);
  EXPECT_EQ(m.at(Dev::outB).kind, DeviceChange::Kind::faulty);
  EXPECT_EQ(m.at(Dev::outB).why, "max_speed 'fast' is not a positive number");
  EXPECT_EQ(m.at(Dev::in1).kind, DeviceChange::Kind::faulty);
  EXPECT_EQ(m.at(Dev::in1).why, "modes lists no mode");
  EXPECT_EQ(m.at(Dev::in4).why, "decimals '-1' is not 0..9");
  EXPECT_EQ(m.at(Dev::in3).kind, DeviceChange::Kind::connected);
  EXPECT_EQ(m.count(Dev::outC), 0u);  // no port: ignored, listed for the log
  ASSERT_EQ(d.ignored().size(), 1u);
  EXPECT_NE(d.ignored()[0].find("ev3-ports:outZ"), std::string::npos);
  EXPECT_FALSE(d.present(Dev::outB));
  d.scan(ch);
  EXPECT_TRUE(ch.empty());  // reported once
  // Garbage values while running are the runtime's (robot_events.txt); any bytes are just bytes.
  t.write(d.dir(Dev::in3) + "/value0", std::string("\0\xff\n", 3));
  const auto r = d.read(Dev::in3, Attr::value0);
  ASSERT_EQ(r.status, Access::ok);
  EXPECT_EQ(r.text.size(), 3u);
}

INSTANTIATE_TEST_SUITE_P(Trees, Generations, ::testing::Values("stretch", "jessie"));

TEST(Devices, NoTreeNoDevices) {
  Ev3Devices d("/nonexistent/sys");
  std::vector<DeviceChange> ch;
  d.scan(ch);
  EXPECT_TRUE(ch.empty());
  EXPECT_FALSE(d.has_battery());
  EXPECT_EQ(d.led_max(Dev::led_left_red), 0);
  EXPECT_EQ(d.read(Dev::outB, Attr::position).status, Access::gone);
}

// ---------------------------------------------------------------- the fault seam

TEST(DevicesFaults, OneSystemCallPerAccessWithHeldDescriptors) {
  Tree t("stretch");
  FaultIo io;
  io.sysfs = true;
  Ev3Devices d(t.root(), io);
  std::vector<DeviceChange> ch;
  d.scan(ch);
  d.read(Dev::outB, Attr::position);  // opens position
  d.write(Dev::outB, Attr::speed_sp, "100");
  const std::size_t opens = io.opens, before = io.calls();
  for (int i = 0; i < 100; ++i) {
    d.read(Dev::outB, Attr::position);
    d.write(Dev::outB, Attr::speed_sp, "200");
  }
  EXPECT_EQ(io.opens, opens);
  EXPECT_EQ(io.calls() - before, 200u);  // one pread, one pwrite: nothing else
  // A rescan costs one listing per class and one pread per known device.
  const std::size_t preads = io.preads;
  d.scan(ch);
  EXPECT_EQ(io.preads - preads, 5u);
}

TEST(DevicesFaults, EnodevMeansUnplugged) {
  Tree t("stretch");
  FaultIo io;
  Ev3Devices d(t.root(), io);
  std::vector<DeviceChange> ch;
  d.scan(ch);
  ASSERT_EQ(d.read(Dev::outC, Attr::position).status, Access::ok);
  io.unplugged.push_back(t.root() + "/class/tacho-motor/motor1");
  const auto r = d.read(Dev::outC, Attr::position);
  EXPECT_EQ(r.status, Access::gone);
  EXPECT_EQ(r.err, ENODEV);
  EXPECT_FALSE(d.present(Dev::outC));
  d.scan(ch);
  EXPECT_TRUE(ch.empty());  // found by the access: not reported twice
  // ENODEV on a write too.
  io.unplugged.push_back(t.root() + "/class/lego-sensor/sensor2");
  EXPECT_EQ(d.write(Dev::in4, Attr::mode, "US-DIST-CM").status, Access::gone);
  // Back (the device reappears under its name): found by the next scan.
  io.unplugged.clear();
  d.scan(ch);
  EXPECT_EQ(ch.size(), 2u);
}

TEST(DevicesFaults, EbusyIsAFailureNotAnUnplug) {
  Tree t("jessie");
  FaultIo io;
  io.write_error["/position"] = EBUSY;
  Ev3Devices d(t.root(), io);
  std::vector<DeviceChange> ch;
  d.scan(ch);
  const auto r = d.write(Dev::outB, Attr::position, "0");
  EXPECT_EQ(r.status, Access::failed);
  EXPECT_EQ(r.err, EBUSY);
  EXPECT_TRUE(d.present(Dev::outB));
  EXPECT_EQ(d.write(Dev::outB, Attr::speed_sp, "10").status, Access::ok);
}

TEST(DevicesFaults, StaleLedAttributeIsOpenedAgain) {
  Tree t("stretch");
  FaultIo io;
  Ev3Devices d(t.root(), io);
  std::vector<DeviceChange> ch;
  d.scan(ch);
  ASSERT_EQ(d.write(Dev::led_right_green, Attr::delay_on, "500").status, Access::ok);
  const std::size_t opens = io.opens;
  // The trigger left timer: the kernel removed delay_on; our descriptor answers ENODEV once.
  io.write_error["led1:green:brick-status/delay_on"] = ENODEV;
  auto r = d.write(Dev::led_right_green, Attr::delay_on, "500");
  EXPECT_EQ(r.status, Access::gone);  // still ENODEV after reopening: the attribute is not there
  io.write_error.clear();
  r = d.write(Dev::led_right_green, Attr::delay_on, "250");
  EXPECT_EQ(r.status, Access::ok);
  EXPECT_GT(io.opens, opens);
  EXPECT_TRUE(d.led_max(Dev::led_right_green) > 0);
}

TEST(DevicesFaults, ReadErrorsAreFailures) {
  Tree t("stretch");
  FaultIo io;
  io.read_error["/value1"] = ENXIO;  // valueN beyond num_values, as on a brick
  Ev3Devices d(t.root(), io);
  std::vector<DeviceChange> ch;
  d.scan(ch);
  const auto r = d.read(Dev::in4, Attr::value1);
  EXPECT_EQ(r.status, Access::failed);
  EXPECT_EQ(r.err, ENXIO);
  EXPECT_TRUE(d.present(Dev::in4));
  // A description that cannot be read makes the device faulty with the reason.
  io.read_error["sensor0/modes"] = EIO;
  Tree t2("jessie");
  Ev3Devices d2(t2.root(), io);
  d2.scan(ch);
  const auto m = by_port(ch);
  EXPECT_EQ(m.at(Dev::in1).kind, DeviceChange::Kind::faulty);
  EXPECT_EQ(m.at(Dev::in1).why, "reading modes failed (EIO)");
}

// ---------------------------------------------------------------- the runtime through the layer

/// The agent program's robot loop on a tree: RobotIo between Ev3Devices and the Runtime.
struct Loop {
  explicit Loop(const std::string& root, ev3io::SysfsIo& io = ev3io::system_io())
      : devices(root, io), rio(devices), rt(RuntimeConfig{}, 0) {
    rio.scan(rt, 0);
    rio.flush(rt, 0);
    drain();
  }
  void run_until(ev3proto::Millis to) {
    for (; now < to; ++now) {
      if (now >= rio.next_scan()) rio.scan(rt, now);
      if (now >= rt.next_deadline()) rio.tick(rt, now);
      rio.flush(rt, now);
      drain();
    }
  }
  void drain() {
    ActionResult r;
    while (rt.poll_result(r)) results.push_back(std::string(to_string(r.outcome)) + ": " + std::string(r.detail.view()));
    Event e;
    while (rt.poll_event(e)) {
      std::string_view p[4];
      std::string s;
      for (std::size_t i = 0, n = e.params(p); i < n; ++i) s += (i ? " " : "") + std::string(p[i]);
      events.push_back(std::to_string(now) + " " + s);
    }
  }
  Ev3Devices devices;
  ev3io::RobotIo rio;
  Runtime rt;
  ev3proto::Millis now = 1;
  std::vector<std::string> results, events;
};

TEST(RobotLoop, DriveUntilTheBumperOnATree) {
  Tree t("stretch");
  Loop l(t.root());
  EXPECT_EQ(l.rt.plugged(), kModelADevices);
  ASSERT_EQ(l.events.size(), 5u);
  const std::string left = l.devices.dir(Dev::outB), touch = l.devices.dir(Dev::in1);
  EXPECT_EQ(t.read(left + "/command"), "reset");
  EXPECT_EQ(t.read(l.devices.dir(Dev::in3) + "/mode"), "COL-COLOR");  // model A's floor mode
  l.rt.led(ev3proto::Led::GREEN);
  l.rio.flush(l.rt, 1);
  EXPECT_EQ(t.read(t.root() + "/class/leds/led0:green:brick-status/brightness"), "255");
  EXPECT_EQ(t.read(t.root() + "/class/leds/led0:red:brick-status/trigger"), "none");
  const std::string_view args[] = {"speed=400"};
  l.rt.control(ev3proto::ControlKind::start, "drive", args, 1, 1);
  l.run_until(500);
  EXPECT_EQ(t.read(left + "/speed_sp"), "400");
  EXPECT_EQ(t.read(left + "/command"), "run-forever");
  t.write(touch + "/value0", "1\n");  // the bumper, at 500
  l.run_until(540);
  EXPECT_EQ(t.read(left + "/command"), "stop");
  EXPECT_EQ(t.read(l.devices.dir(Dev::outC) + "/command"), "stop");
  ASSERT_EQ(l.results.size(), 1u);
  EXPECT_EQ(l.results[0], "interrupted: interrupted by OBSTACLE_DETECTED on in1");
  EXPECT_EQ(l.events.back().substr(0, 4), "501 ");  // read in the first tick after the press
  EXPECT_EQ(l.rio.stats().failed_reads + l.rio.stats().failed_writes, 0u);
}

TEST(RobotLoop, UnplugDuringDriveAndBackWithinASecond) {
  Tree t("jessie");
  FaultIo io;
  Loop l(t.root(), io);
  const std::string_view args[] = {"speed=300"};
  l.rt.control(ev3proto::ControlKind::start, "drive", args, 1, 1);
  l.run_until(300);
  const std::string right = l.devices.dir(Dev::outC);
  io.unplugged.push_back(right);  // ENODEV from now on, gone from the listing
  l.run_until(330);
  EXPECT_EQ(t.read(l.devices.dir(Dev::outB) + "/command"), "stop");  // the other motor stopped
  ASSERT_FALSE(l.events.empty());
  EXPECT_EQ(l.events.back(), "301 DEVICE_DISCONNECTED outC");
  EXPECT_EQ(l.rt.plugged() & kMotorRight, 0u);
  io.unplugged.clear();  // plugged again
  l.run_until(1400);
  EXPECT_EQ(l.events.back(), "1000 DEVICE_CONNECTED outC lego-ev3-l-motor");  // the scan after
  EXPECT_EQ(l.rt.plugged(), kModelADevices);
}

TEST(RobotLoop, EbusyFromTheDriverIsReported) {
  Tree t("stretch");
  FaultIo io;
  io.write_error["/command"] = EBUSY;
  Loop l(t.root(), io);
  const std::string_view args[] = {"speed=300"};
  l.rt.control(ev3proto::ControlKind::start, "drive", args, 1, 1);
  l.run_until(50);
  ASSERT_EQ(l.results.size(), 1u);
  EXPECT_EQ(l.results[0], "failed: outB: writing command 'run-forever' failed (EBUSY)");
}

}  // namespace
