// ev3-sim's physics, through the robot's tree as the agent drives it: a wheel turn moves the robot
// one circumference, the stop actions' distances (coast > brake > hold, the thesis' 1-5 cm and
// <= 2 cm), the ultrasonic against the geometry, walls that cannot be crossed, robots that see
// and stop each other, turns about the axle midpoint, the colour under the sensor, the battery.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>

#include "ev3sim/sim.hpp"

namespace {

using namespace ev3sim;

constexpr double kCircumference = kPi * 5.6;  // model A's wheel, cm

std::unique_ptr<Sim> make_sim(const std::string& world_text) {
  World w;
  const std::string err = parse_world(world_text, "test", w);
  EXPECT_EQ(err, "");
  return std::make_unique<Sim>(w);
}

Robot& add(Sim& sim, const std::string& name, double x, double y, double heading_deg) {
  RobotConfig cfg;
  cfg.name = name;
  cfg.start.p = {x, y};
  cfg.start.heading = deg2rad(heading_deg);
  EXPECT_EQ(sim.add_robot(cfg), "");
  return *sim.robot(name);
}

// The attribute's node, found as a program finds it: through the class directory's symlink
// ("../../devices/...").
Ino attr_node(Robot& r, const std::string& dev, const std::string& attr) {
  const std::string link = dev == "battery" ? "class/power_supply/lego-ev3-battery" : r.class_path(dev);
  const Node* l = r.tree().node(r.tree().resolve(link));
  EXPECT_TRUE(l && l->kind == NodeKind::Link) << dev;
  const Ino n = l ? r.tree().resolve(l->target.substr(6) + "/" + attr) : 0;
  EXPECT_NE(n, 0u) << dev << "/" << attr;
  return n;
}

// Writes through the tree, as the agent's pwrite would.
int write(Robot& r, const std::string& port, const std::string& attr, const std::string& value) {
  return r.tree().write(attr_node(r, port, attr), value).err;
}

std::string read(Robot& r, const std::string& port, const std::string& attr) {
  const Ino n = attr_node(r, port, attr);
  std::string v = r.tree().read(n).data;
  if (!v.empty() && v.back() == '\n') v.pop_back();
  return v;
}

void both(Robot& r, const std::string& attr, const std::string& value) {
  r.set_now(0);
  EXPECT_EQ(write(r, "outB", attr, value), 0);
  EXPECT_EQ(write(r, "outC", attr, value), 0);
}

void run_ms(Sim& sim, int ms) { sim.advance_to(sim.now() + ms * 1000LL); }

const char* kOpen = "bounds 0 0 1000 400\n";

// The tacho-motor class notifies `state` on every change (sysfs_notify): at the command that
// starts the motor and when it stops, not while it keeps running.
TEST(Physics, MotorStateIsNotifiedOnEveryChange) {
  auto sim = make_sim(kOpen);
  Robot& r = add(*sim, "r", 100, 200, 0);
  const Ino state = attr_node(r, "outB", "state");
  r.tree().take_notified();
  r.set_now(sim->now());
  EXPECT_EQ(write(r, "outB", "time_sp", "300"), 0);
  EXPECT_TRUE(r.tree().take_notified().empty());
  const std::uint64_t before = r.tree().node(state)->event;
  EXPECT_EQ(write(r, "outB", "speed_sp", "500"), 0);
  EXPECT_EQ(write(r, "outB", "command", "run-timed"), 0);
  EXPECT_EQ(r.tree().take_notified(), std::vector<Ino>{state});
  EXPECT_EQ(read(r, "outB", "state"), "running");
  run_ms(*sim, 200);
  EXPECT_TRUE(r.tree().take_notified().empty());
  EXPECT_EQ(r.tree().node(state)->event, before + 1);
  run_ms(*sim, 150);
  EXPECT_EQ(read(r, "outB", "state"), "");
  EXPECT_EQ(r.tree().take_notified(), std::vector<Ino>{state});
  EXPECT_EQ(r.tree().node(state)->event, before + 2);
}

TEST(Physics, OneWheelTurnMovesOneCircumference) {
  auto sim = make_sim(kOpen);
  Robot& r = add(*sim, "a", 100, 200, 0);
  both(r, "position_sp", "360");
  both(r, "speed_sp", "200");
  both(r, "stop_action", "hold");
  both(r, "command", "run-to-rel-pos");
  run_ms(*sim, 4000);
  EXPECT_EQ(read(r, "outB", "position"), "360");
  EXPECT_EQ(read(r, "outC", "position"), "360");
  EXPECT_EQ(read(r, "outB", "state"), "holding");
  // The body slides a little past the wheels' stop (traction); at 200 deg/s that is < 0.1 cm.
  EXPECT_NEAR(r.pose().p.x - 100, kCircumference, 0.1);
  EXPECT_NEAR(r.pose().p.y, 200, 1e-6);
}

// Drives straight at @p speed until steady, stops with @p action, returns how far the robot went
// after the stop command (cm).
double stop_distance(int speed, const char* action) {
  auto sim = make_sim(kOpen);
  Robot& r = add(*sim, "a", 100, 200, 0);
  both(r, "speed_sp", std::to_string(speed));
  both(r, "stop_action", action);
  both(r, "command", "run-forever");
  run_ms(*sim, 1500);
  const double at_stop = r.pose().p.x;
  both(r, "command", "stop");
  run_ms(*sim, 2000);
  return r.pose().p.x - at_stop;
}

TEST(Physics, StopDistancesCoastBrakeHold) {
  // The thesis (docs/brief.md section 7): coast 1-5 cm depending on speed, hold <= 2 cm.
  std::printf("speed (deg/s, cm/s)   coast    brake    hold   (cm travelled after `stop`)\n");
  for (int speed : {263, 525, 788, 1050}) {
    const double coast = stop_distance(speed, "coast");
    const double brake = stop_distance(speed, "brake");
    const double hold = stop_distance(speed, "hold");
    std::printf("%4d  %5.1f            %5.2f    %5.2f    %5.2f\n", speed, speed / 360.0 * kCircumference, coast,
                brake, hold);
    EXPECT_GT(coast, brake) << speed;
    EXPECT_GT(brake, hold) << speed;
    EXPECT_GE(coast, 0.9) << speed;
    EXPECT_LE(coast, 5.0) << speed;
    EXPECT_LE(hold, 2.0) << speed;
    EXPECT_GE(hold, 0.0) << speed;
  }
}

TEST(Physics, UltrasonicMatchesGeometry) {
  // A wall at x = 200, a box whose near face is at y = 300.
  auto sim = make_sim("bounds 0 0 1000 1000\nwall 200 0 200 150\nbox 480 300 40 40\n");
  Robot& r = add(*sim, "a", 100, 100, 0);
  run_ms(*sim, 10);
  // The sensor sits 11 cm ahead of the axle: 200 - 111 = 89 cm.
  EXPECT_EQ(read(r, "in4", "value0"), "890");
  // 45 degrees up: the ray meets the wall at y = 100 + 89 (it misses nothing else).
  ASSERT_TRUE(sim->control("place 100 30 45").ok);
  run_ms(*sim, 10);
  const Vec2 o = r.ultrasonic_origin();
  const double expect = (200 - o.x) / std::cos(deg2rad(45));
  EXPECT_NEAR(std::stod(read(r, "in4", "value0")) / 10, expect, 0.05);
  // Facing the box from below: its face at y = 300.
  ASSERT_TRUE(sim->control("place 500 150 90").ok);
  run_ms(*sim, 10);
  EXPECT_EQ(read(r, "in4", "value0"), std::to_string(static_cast<int>(std::lround((300 - 161) * 10.0))));
  // Nothing within 255 cm: 2550.
  ASSERT_TRUE(sim->control("place 700 100 90").ok);
  run_ms(*sim, 10);
  EXPECT_EQ(read(r, "in4", "value0"), "2550");
  // The same distance in inches (US-DIST-IN, 1 decimal).
  ASSERT_TRUE(sim->control("place 500 150 90").ok);
  r.set_now(sim->now());
  EXPECT_EQ(write(r, "in4", "mode", "US-DIST-IN"), 0);
  run_ms(*sim, 60);
  EXPECT_EQ(read(r, "in4", "value0"), std::to_string(static_cast<int>(std::lround(139 / 2.54 * 10))));
}

TEST(Physics, NeverPassesThroughAWall) {
  // A thin wall across the robot's way, approached at full speed and at an angle.
  for (double heading : {0.0, 20.0, -35.0}) {
    auto sim = make_sim("bounds 0 0 600 400\nwall 300 0 300 400\n");
    Robot& r = add(*sim, "a", 150, 200, heading);
    both(r, "speed_sp", "1050");
    both(r, "command", "run-forever");
    for (int i = 0; i < 800; ++i) {
      run_ms(*sim, 10);
      for (Vec2 v : r.footprint()) ASSERT_LE(v.x, 300.0 + 1e-9) << "heading " << heading << " step " << i;
    }
    // Head-on (and at 20 degrees) the bumper meets the wall; at 35 degrees a corner does first.
    EXPECT_EQ(r.bumper(), heading != -35.0) << heading;
    EXPECT_EQ(read(r, "in1", "value0"), heading != -35.0 ? "1" : "0") << heading;
    EXPECT_EQ(read(r, "outB", "speed"), "0") << heading;
    EXPECT_NE(read(r, "outB", "state").find("stalled"), std::string::npos) << heading;
    // Reversing away works.
    both(r, "speed_sp", "-300");
    both(r, "command", "run-forever");
    run_ms(*sim, 1000);
    EXPECT_FALSE(r.bumper()) << heading;
    EXPECT_LT(r.footprint()[1].x, 295.0) << heading;
  }
}

TEST(Physics, RobotsSeeAndStopEachOther) {
  auto sim = make_sim(kOpen);
  Robot& a = add(*sim, "a", 100, 200, 0);
  Robot& b = add(*sim, "b", 200, 200, 180);
  run_ms(*sim, 10);
  // a's sensor at x = 111; b faces a, its bumper at x = 200 - 12 = 188.
  EXPECT_EQ(read(a, "in4", "value0"), "770");
  both(a, "speed_sp", "500");
  both(a, "command", "run-forever");
  run_ms(*sim, 5000);
  EXPECT_TRUE(a.bumper());
  EXPECT_NEAR(a.pose().p.x + 12, 188, 0.05);
  EXPECT_TRUE(b.bumper());  // bumper to bumper
  EXPECT_NEAR(b.pose().p.x, 200, 1e-9);  // not pushed
  // US-LISTEN: b hears a's ultrasonic.
  b.set_now(sim->now());
  EXPECT_EQ(write(b, "in4", "mode", "US-LISTEN"), 0);
  run_ms(*sim, 60);
  EXPECT_EQ(read(b, "in4", "value0"), "1");
}

TEST(Physics, TurnInPlaceAboutTheAxleMidpoint) {
  auto sim = make_sim(kOpen);
  Robot& r = add(*sim, "a", 300, 200, 0);
  r.set_now(0);
  // Wheels opposite, a quarter turn of the robot: each wheel travels (pi/2) * b/2.
  const double wheel_cm = kPi / 2 * 12.0 / 2;
  const int counts = static_cast<int>(std::lround(wheel_cm / kCircumference * 360));
  EXPECT_EQ(write(r, "outB", "position_sp", std::to_string(-counts)), 0);
  EXPECT_EQ(write(r, "outC", "position_sp", std::to_string(counts)), 0);
  both(r, "speed_sp", "150");
  both(r, "stop_action", "hold");
  both(r, "command", "run-to-rel-pos");
  run_ms(*sim, 3000);
  EXPECT_NEAR(rad2deg(r.pose().heading), 90.0, 1.0);
  EXPECT_NEAR(r.pose().p.x, 300, 0.05);
  EXPECT_NEAR(r.pose().p.y, 200, 0.05);
}

TEST(Physics, ColourSensorReadsTheFloor) {
  auto sim = make_sim("bounds 0 0 400 400\nground white\nfloor green poly 100 100 200 100 150 190\n");
  Robot& r = add(*sim, "a", 30, 30, 0);
  r.set_now(0);
  EXPECT_EQ(write(r, "in3", "mode", "COL-COLOR"), 0);
  run_ms(*sim, 60);
  EXPECT_EQ(read(r, "in3", "value0"), "6");  // white ground
  // Drive the sensor (8 cm ahead of the axle) onto the triangle.
  ASSERT_TRUE(sim->control("place 142 130 0").ok);
  run_ms(*sim, 5);
  EXPECT_EQ(read(r, "in3", "value0"), "3");  // green
}

TEST(Physics, BatteryDrainsWithMotorUse) {
  auto idle_sim = make_sim(kOpen);
  Robot& idle = add(*idle_sim, "a", 100, 200, 0);
  auto busy_sim = make_sim(kOpen);
  Robot& busy = add(*busy_sim, "a", 100, 200, 0);
  both(busy, "speed_sp", "1050");
  both(busy, "command", "run-forever");
  run_ms(*busy_sim, 10000);
  run_ms(*idle_sim, 10000);
  both(busy, "command", "stop");
  run_ms(*busy_sim, 1000);
  run_ms(*idle_sim, 1000);
  // Stopped again, the open-circuit voltage shows the charge the motors used.
  EXPECT_LT(busy.volts(), idle.volts() - 0.002);
  EXPECT_LT(idle.volts(), 7.992);
  // Under load the voltage sags and the current shows the motors.
  both(busy, "command", "run-forever");
  run_ms(*busy_sim, 500);
  EXPECT_GT(std::stoi(read(busy, "battery", "current_now")), 1000000);
}

TEST(Physics, GyroFollowsTheHeading) {
  auto sim = make_sim(kOpen);
  Robot& r = add(*sim, "a", 300, 200, 0);
  ASSERT_TRUE(sim->control("plug in2 lego-ev3-gyro").ok);
  r.set_now(sim->now());
  EXPECT_EQ(write(r, "outB", "speed_sp", "300"), 0);
  EXPECT_EQ(write(r, "outC", "speed_sp", "-300"), 0);
  both(r, "command", "run-forever");
  run_ms(*sim, 800);
  // Turning right (clockwise): the gyro counts up, as the real one does.
  const double turned_cw = -rad2deg(wrap_angle(r.pose().heading));
  EXPECT_NEAR(std::stod(read(r, "in2", "value0")), turned_cw, 1.0);
  EXPECT_GT(turned_cw, 30);
}

}  // namespace
