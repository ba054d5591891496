// The link between a robot node and the robot runtime (robot_link.hpp), without a device layer:
// what the agent announces, the devices missing at start, a behaviour control reaching the runtime
// and its result reaching the master, a bad argument failing, BATTERY_LOW reaching the master and
// switching both off; the robot's events reaching the master as EVENT(name, port), and an obstacle
// that interrupts the drive as ACTION_INTERR only; the robot's check of a BEHAVIOUR on receipt.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "fixed_timers.hpp"
#include "ev3proto/robot/behaviours.hpp"
#include "ev3proto/robot_link.hpp"
#include "../robot/fixtures.hpp"
#include "symbolic.hpp"

namespace {
using namespace ev3proto;
namespace robot = ev3proto::robot;

constexpr BehaviourSpec kLinkBehs[] = {{"wait", 0}, {"drive", robot::kMotors | robot::kTouch}};

struct Rig {
  Node<>::Config cfg;
  Node<> node;
  robot::Runtime rt;
  robot::RobotLink<Node<>> link;
  std::vector<std::string> notes, writes;

  static Node<>::Config make_config(bool ev3dev_tree) {
    Node<>::Config c;
    c.agent.timers = ev3test::fixed_timers();
    c.agent.caps = Capabilities{"A", kLinkBehs, 2, robot::announced_devices(ev3dev_tree), robot::kModelADeviceNames,
                                std::size(robot::kModelADeviceNames)};
    c.agent.temp_id = 50001;
    return c;
  }
  explicit Rig(bool ev3dev_tree)
      : cfg(make_config(ev3dev_tree)), node(cfg, 0), rt(robot::RuntimeConfig{}, 0), link(cfg.agent.caps.devices) {}

  void note(const robot::LinkNote& n) {
    using K = robot::LinkNote::Kind;
    std::string s;
    switch (n.kind) {
      case K::result: s = "result " + std::to_string(static_cast<int>(n.result.outcome)); break;
      case K::event: s = "event " + std::string(robot::to_string(n.event.kind)); break;
      case K::report: s = "report"; break;
      case K::missing: s = "missing " + std::to_string(n.bits); break;
      case K::control: s = "control " + std::string(to_string(n.control)) + " " + std::string(n.name); break;
      case K::watchdog: s = "watchdog"; break;
    }
    notes.push_back(s + (n.taken ? " taken" : ""));
  }
  void exchange(Millis now) {
    link.exchange(
        node, rt, now, [](const NodeEvent&) {},
        [this] {
          robot::Write w;
          while (rt.poll_write(w))
            writes.push_back(std::string(robot::to_string(w.dev)) + "/" + std::string(robot::to_string(w.attr)) +
                             "=" + std::string(w.value.view()));
        },
        [this](const robot::LinkNote& n) { note(n); });
  }
  void datagram(const std::string& d, Millis now) {
    node.handle_datagram(d, 1, now);
    exchange(now);
  }
  std::vector<std::string> sent() {
    std::vector<std::string> out;
    NodeTransmit t;
    while (node.poll_transmit(t)) out.push_back(ev3test::symbolic(t.bytes));
    return out;
  }
};

bool has(const std::vector<std::string>& v, const std::string& part) {
  for (const std::string& s : v)
    if (s.find(part) != std::string::npos) return true;
  return false;
}

TEST(RobotLink, AnnouncesModelADevicesOnlyOnAnEv3devTree) {
  EXPECT_EQ(robot::announced_devices(true), robot::kModelADevices);
  EXPECT_EQ(robot::announced_devices(false), 0u);
}

TEST(RobotLink, DevicesMissingAtStartAreToldTheMasterOnceSynced) {
  Rig r(true);  // an ev3dev tree with nothing plugged
  r.exchange(0);
  EXPECT_TRUE(r.notes.empty());  // no master to tell yet
  r.datagram("1:7:1:2:50001", 10);  // MASTER: id 7
  ASSERT_EQ(r.notes.size(), 5u) << ::testing::PrintToString(r.notes);  // the first, then each other one
  EXPECT_EQ(r.notes[0], "missing " + std::to_string(robot::kModelADevices) + " taken");
  const auto out = r.sent();
  EXPECT_TRUE(has(out, "ACK"));
  EXPECT_TRUE(has(out, "EVENT #")) << ::testing::PrintToString(out);
  EXPECT_TRUE(has(out, "DEVICE_DISCONNECTED"));
  // Spec: no behaviour while a device is missing (devOk); the NOT names the first one missing.
  r.datagram("1:7:2:7:wait:seconds=1", 20);
  EXPECT_EQ(r.sent(), std::vector<std::string>{
                          "7->1 NOT #7 2 \"missing device: the robot has no left motor (no behaviour runs until it is back)\""});  // #2..#6: the EVENTs
}

// The runtime's contact watchdog is fed the agent core's last contact with its master on every
// exchange (robot_test's robot_watchdog transcript shows what it does with it).
TEST(RobotLink, FeedsTheRuntimeTheLastContactWithTheMaster) {
  Rig r(false);
  r.exchange(0);
  EXPECT_EQ(r.rt.run_until(), 500u);  // armed by the core's start (last heard: its creation)
  r.datagram("1:7:1:2:50001", 10);    // MASTER
  EXPECT_EQ(r.rt.last_contact(), 10u);
  r.node.advance(90);
  r.exchange(90);
  EXPECT_EQ(r.rt.last_contact(), 10u);  // time alone is no contact
  r.datagram("1:7:2:6:1", 95);          // PONG
  EXPECT_EQ(r.rt.last_contact(), 95u);
  EXPECT_EQ(r.rt.run_until(), 595u);
}

TEST(RobotLink, WithoutDevicesWaitRunsToActionOkAndDriveIsRefused) {
  Rig r(false);  // a PC: no devices announced, none missing
  r.datagram("1:7:1:2:50001", 10);
  EXPECT_TRUE(r.notes.empty());
  r.sent();
  r.datagram("1:7:2:7:drive:speed=100", 20);  // needs devices the robot has not got: NOT names the first
  EXPECT_EQ(r.sent(), std::vector<std::string>{"7->1 NOT #2 2 \"missing device: the robot has no left motor (drive needs it)\""});
  r.datagram("1:7:3:7:wait:seconds=0.5", 30);
  r.datagram("1:7:4:8", 40);  // START
  EXPECT_TRUE(has(r.notes, "control start wait"));
  r.sent();
  for (Millis t = 40; t <= 600; t += 10) {
    if (t >= r.rt.next_deadline()) r.rt.tick(t);
    r.node.advance(t);
    r.exchange(t);
  }
  EXPECT_TRUE(has(r.notes, "result 1 taken"));  // Outcome::finished -> action_ok
  const auto out = r.sent();
  EXPECT_TRUE(has(out, "ACTION_OK")) << ::testing::PrintToString(out) << ::testing::PrintToString(r.notes);
}

TEST(RobotLink, BadArgumentFailsAtStartAndBatteryLowSwitchesBothOff) {
  Rig r(false);
  r.rt.battery_present(true);
  r.datagram("1:7:1:2:50001", 10);
  EXPECT_FALSE(robot::RobotLink<Node<>>::shut_down(r.node, r.rt));
  r.datagram("1:7:2:7:wait:seconds=x", 20);
  r.datagram("1:7:3:8", 30);  // START: the runtime cannot build the plan
  EXPECT_TRUE(has(r.sent(), "ACTION_ERR"));
  std::vector<std::string> out;
  for (Millis t = 1000; t <= 5000; t += 1000) {
    r.rt.reading(robot::Dev::battery, robot::Attr::voltage_now, "5900000\n", t);
    r.rt.tick(t);
    r.exchange(t);
    for (const std::string& s : r.sent()) out.push_back(s);
  }
  EXPECT_TRUE(has(r.notes, "event BATTERY_LOW taken"));
  EXPECT_TRUE(has(out, "EVENT #")) << (out.empty() ? "" : out.back());
  EXPECT_TRUE(has(out, "BATTERY_LOW"));
  EXPECT_TRUE(r.rt.off());
  EXPECT_EQ(r.node.agent().state(), State::OFF);
  EXPECT_TRUE(robot::RobotLink<Node<>>::shut_down(r.node, r.rt));
}

// A behaviour in the language through the core and the runtime (a capability table of this test's
// own: the agent's lists wait and drive only): each finished action is an ACTION_OK with the next id;
// a custom definition that does not check fails at START (ACTION_ERR), RESTART tries again.
TEST(RobotLink, CustomBehaviourGivesOneActionOkPerFinishedAction) {
  static constexpr BehaviourSpec kCustom[] = {{"custom", 0}};
  Node<>::Config cfg = Rig::make_config(false);
  cfg.agent.caps = Capabilities{"A", kCustom, 1, 0};
  Node<> node(cfg, 0);
  robot::Runtime rt(robot::RuntimeConfig{}, 0);
  robot::RobotLink<Node<>> link(cfg.agent.caps.devices);
  std::vector<std::string> out;
  auto exchange = [&](Millis now) {
    link.exchange(
        node, rt, now, [](const NodeEvent&) {}, [&] { for (robot::Write w; rt.poll_write(w);) {} },
        [](const robot::LinkNote&) {});
    NodeTransmit t;
    while (node.poll_transmit(t)) out.push_back(ev3test::symbolic(t.bytes));
  };
  auto run = [&](Millis from, Millis to) {
    for (Millis t = from; t <= to; t += 10) {
      if (t >= rt.next_deadline()) rt.tick(t);
      node.advance(t);
      exchange(t);
    }
  };
  node.handle_datagram("1:7:1:2:50001", 1, 10);
  exchange(10);
  node.handle_datagram("1:7:2:7:custom:behaviour two;state a = wait 100ms -> b;state b = wait 200ms -> end", 1, 20);
  node.handle_datagram("1:7:3:8", 1, 30);  // START
  exchange(30);
  out.clear();
  run(40, 600);
  std::vector<std::string> oks;
  for (const std::string& s : out)
    if (s.find("ACTION_") != std::string::npos) oks.push_back(s);
  ASSERT_EQ(oks.size(), 2u) << ::testing::PrintToString(out);
  EXPECT_NE(oks[0].find("ACTION_OK"), std::string::npos);
  EXPECT_EQ(oks[0].substr(oks[0].rfind(' ') + 1), "0]") << oks[0];  // "7->1 REPORT #4 1 1 [7->1 ACTION_OK #4 0]"
  EXPECT_NE(oks[1].find("ACTION_OK"), std::string::npos);
  EXPECT_EQ(oks[1].substr(oks[1].rfind(' ') + 1), "1]") << oks[1];
  // A definition that does not check: ACTION_ERR at START.
  node.handle_datagram("1:7:4:7:custom:behaviour bad;state a = trun 90 -> end", 1, 700);
  node.handle_datagram("1:7:5:8", 1, 710);
  out.clear();
  exchange(710);
  EXPECT_TRUE(has(out, "ACTION_ERR")) << ::testing::PrintToString(out);
}

TEST(RobotLink, TheRobotChecksABehaviourOnReceiptAndNotRefusesItWithItsReason) {
  static constexpr BehaviourSpec kCustom[] = {{"custom", 0}};
  robot::Runtime rt(robot::RuntimeConfig{}, 0);
  Node<>::Config cfg = Rig::make_config(false);
  cfg.agent.caps = Capabilities{"A", kCustom, 1, 0};
  cfg.agent.check = robot::behaviour_check(rt);
  Node<> node(cfg, 0);
  robot::RobotLink<Node<>> link(cfg.agent.caps.devices);
  std::vector<std::string> out, controls;
  auto exchange = [&](Millis now) {
    link.exchange(
        node, rt, now, [](const NodeEvent&) {}, [&] { for (robot::Write w; rt.poll_write(w);) {} },
        [&](const robot::LinkNote& n) {
          if (n.kind == robot::LinkNote::Kind::control) controls.push_back(std::string(to_string(n.control)));
        });
    NodeTransmit t;
    while (node.poll_transmit(t)) out.push_back(ev3test::symbolic(t.bytes));
  };
  auto recv = [&](const std::string& d, Millis now) {
    out.clear();
    node.handle_datagram(d, 1, now);
    exchange(now);
    return out;
  };
  recv("1:7:1:2:50001", 10);
  // Does not parse: NOT with the parser's place and words; nothing reaches the runtime.
  EXPECT_EQ(recv("1:7:2:7:custom:behaviour bad;state a = trun 90 -> end", 20),
            std::vector<std::string>{"7->1 NOT #2 2 \"line 1 col 25: unknown action 'trun' (actions: run, drive, "
                                     "turn, stop, pause, wait, repeat)\""});
  // Needs a device model A lacks: NOT naming it.
  EXPECT_EQ(recv("1:7:3:7:custom:behaviour g;state a = pause 1s -> a;when gyro > 90 -> end", 30),
            std::vector<std::string>{"7->1 NOT #3 3 \"line 1 col 42: the robot has no gyro sensor (when gyro needs it)\""});
  // A BEHAVIOUR argument out of the definition's params: refused too.
  EXPECT_EQ(recv("1:7:4:7:custom:behaviour w;state a = wait 1s -> end:speed=3", 40),
            std::vector<std::string>{"7->1 NOT #4 4 \"argument 'speed=3': unknown param 'speed' (behaviour w has no params)\""});
  EXPECT_EQ(recv("1:7:5:8", 50), std::vector<std::string>{"7->1 NOT #5 5 \"no behaviour\""});
  EXPECT_TRUE(controls.empty()) << ::testing::PrintToString(controls);
  // Checks: ACK; a refused request after it keeps it; START runs it (one ACTION_OK per finished action).
  EXPECT_EQ(recv("1:7:6:7:custom:behaviour ok;state a = wait 100ms -> end", 60), std::vector<std::string>{"7->1 ACK #6 6"});
  EXPECT_EQ(recv("1:7:7:7:custom:behaviour bad;state a = trun 90 -> end", 65).size(), 1u);
  recv("1:7:8:8", 70);
  EXPECT_EQ(controls, std::vector<std::string>{"start"});
  std::vector<std::string> all;
  for (Millis t = 80; t <= 300; t += 10) {
    if (t >= rt.next_deadline()) rt.tick(t);
    node.advance(t);
    out.clear();
    exchange(t);
    all.insert(all.end(), out.begin(), out.end());
  }
  EXPECT_TRUE(has(all, "ACTION_OK")) << ::testing::PrintToString(all);
  EXPECT_FALSE(has(all, "ACTION_ERR")) << ::testing::PrintToString(all);
}

/// Model A plugged on its default ports (the runtime's DEVICE_CONNECTED events at @p now).
void plug_model_a(Rig& r, Millis now) {
  using robot::Dev;
  r.rt.device_connected(ev3test::large_motor(Dev::outB), now);
  r.rt.device_connected(ev3test::large_motor(Dev::outC), now);
  r.rt.device_connected(ev3test::sensor(Dev::in1, "lego-ev3-touch", "TOUCH", "TOUCH", "0"), now);
  r.rt.device_connected(ev3test::sensor(Dev::in3, "lego-ev3-color", "COL-REFLECT COL-AMBIENT COL-COLOR", "COL-COLOR", "0"), now);
  r.rt.device_connected(ev3test::sensor(Dev::in4, "lego-ev3-us", "US-DIST-CM US-DIST-IN US-LISTEN", "US-DIST-CM", "1"), now);
  r.exchange(now);
}

/// The bumper reads @p pressed at @p now (one control tick).
void bumper(Rig& r, bool pressed, Millis now) {
  r.rt.reading(robot::Dev::in1, robot::Attr::value0, pressed ? "1\n" : "0\n", now);
  r.rt.tick(now);
  r.node.advance(now);
  r.exchange(now);
}

TEST(RobotLink, NormalEventsReachTheMasterAsEventWithTheirPort) {
  Rig r(true);
  plug_model_a(r, 0);
  r.datagram("1:7:1:2:50001", 10);  // MASTER: synced, nothing missing
  EXPECT_FALSE(has(r.notes, "missing"));
  r.sent();
  // WORKING with `wait` (no motion): the bumper pressed is EVENT OBSTACLE_DETECTED in1, the wait
  // goes on.
  r.datagram("1:7:2:7:wait:seconds=100", 20);
  r.datagram("1:7:3:8", 30);
  ASSERT_EQ(r.node.agent().state(), State::WORKING);
  r.sent();
  bumper(r, true, 100);
  auto out = r.sent();
  EXPECT_TRUE(has(out, "EVENT #4 OBSTACLE_DETECTED in1")) << ::testing::PrintToString(out);
  EXPECT_FALSE(has(out, "ACTION_INTERR"));
  EXPECT_TRUE(has(r.notes, "event OBSTACLE_DETECTED taken"));
  EXPECT_EQ(r.node.agent().state(), State::WORKING);
  bumper(r, true, 200);  // held: one event per press
  EXPECT_TRUE(r.sent().empty());
  bumper(r, false, 300);
  bumper(r, false, 400);
  // A device the model does not use, plugged and unplugged: EVENT with its port, nothing else.
  r.rt.device_connected(ev3test::sensor(robot::Dev::in2, "lego-ev3-gyro", "GYRO-ANG GYRO-RATE", "GYRO-ANG", "0"), 500);
  r.exchange(500);
  out = r.sent();
  EXPECT_TRUE(has(out, "EVENT #5 DEVICE_CONNECTED in2")) << ::testing::PrintToString(out);
  r.rt.device_disconnected(robot::Dev::in2, 510);
  r.exchange(510);
  out = r.sent();
  EXPECT_TRUE(has(out, "EVENT #6 DEVICE_DISCONNECTED in2")) << ::testing::PrintToString(out);
  EXPECT_EQ(r.node.agent().state(), State::WORKING);
}

TEST(RobotLink, AnObstacleThatInterruptsTheDriveIsActionInterrOnly) {
  Rig r(true);
  plug_model_a(r, 0);
  r.datagram("1:7:1:2:50001", 10);
  r.datagram("1:7:2:7:drive:speed=400", 20);
  r.datagram("1:7:3:8", 30);
  ASSERT_EQ(r.node.agent().state(), State::WORKING);
  r.sent();
  bumper(r, true, 100);
  const auto out = r.sent();
  EXPECT_TRUE(has(out, "ACTION_INTERR #4 0 OBSTACLE_DETECTED")) << ::testing::PrintToString(out);
  EXPECT_FALSE(has(out, "EVENT")) << ::testing::PrintToString(out);
  EXPECT_TRUE(has(r.notes, "event OBSTACLE_DETECTED")) << ::testing::PrintToString(r.notes);
  EXPECT_FALSE(has(r.notes, "event OBSTACLE_DETECTED taken"));
}

TEST(RobotLink, DeviceEventsCarryTheirPort) {
  Rig r(true);
  plug_model_a(r, 0);
  r.datagram("1:7:1:2:50001", 10);
  r.sent();
  // Two model devices unplugged: the first is DeviceUnplugged (devOk FALSE), the second a
  // RobotEvent; replugged, the first back a RobotEvent, the last DevicePlugged (devOk TRUE).
  r.rt.device_disconnected(robot::Dev::in3, 100);
  r.rt.device_disconnected(robot::Dev::in4, 100);
  r.exchange(100);
  auto out = r.sent();
  ASSERT_EQ(out.size(), 2u) << ::testing::PrintToString(out);
  EXPECT_TRUE(has(out, "EVENT #2 DEVICE_DISCONNECTED in3"));
  EXPECT_TRUE(has(out, "EVENT #3 DEVICE_DISCONNECTED in4"));
  EXPECT_FALSE(r.node.agent().dev_ok());
  r.rt.device_connected(ev3test::sensor(robot::Dev::in3, "lego-ev3-color", "COL-REFLECT COL-AMBIENT COL-COLOR", "COL-COLOR", "0"), 200);
  r.exchange(200);
  EXPECT_FALSE(r.node.agent().dev_ok());
  r.rt.device_connected(ev3test::sensor(robot::Dev::in4, "lego-ev3-us", "US-DIST-CM US-DIST-IN US-LISTEN", "US-DIST-CM", "1"), 300);
  r.exchange(300);
  out = r.sent();
  ASSERT_EQ(out.size(), 2u) << ::testing::PrintToString(out);
  EXPECT_TRUE(has(out, "EVENT #4 DEVICE_CONNECTED in3"));
  EXPECT_TRUE(has(out, "EVENT #5 DEVICE_CONNECTED in4"));
  EXPECT_TRUE(r.node.agent().dev_ok());
}

TEST(RobotLink, TheFirstMissingDeviceIsToldWithItsPort) {
  Rig r(true);
  r.rt.device_connected(ev3test::large_motor(robot::Dev::outB), 0);
  r.rt.device_connected(ev3test::large_motor(robot::Dev::outC), 0);
  r.exchange(0);
  r.datagram("1:7:1:2:50001", 10);  // ultrasonic (bit 4), touch, colour missing: the first is in4
  const auto out = r.sent();
  EXPECT_TRUE(has(out, "EVENT #2 DEVICE_DISCONNECTED in4"));  // DeviceUnplugged
  EXPECT_TRUE(has(out, "EVENT #3 DEVICE_DISCONNECTED in1")) << ::testing::PrintToString(out);  // RobotEvent
  EXPECT_TRUE(has(out, "EVENT #4 DEVICE_DISCONNECTED in3"));
}

}  // namespace
