// The robot logic as firmware builds it: -fno-exceptions -fno-rtti, no gtest. Runs the runtime
// through model A's discovery, a `drive` stopped by the bumper, a pause and resume (the master
// lost), a DriveDistance to its end, LEDs, a garbage value, an unplug, and BATTERY_LOW; exits
// non-zero on the first failed check.
#include <cstdio>
#include <cstring>
#include <string_view>

#include "ev3proto/robot_runtime.hpp"
#include "fixtures.hpp"

#include "../firmware_check.hpp"

namespace {
using namespace ev3proto::robot;
using ev3test::large_motor;
using ev3test::sensor;

struct Counts {
  int writes = 0, stops = 0, results = 0, events = 0;
  Outcome last = Outcome::running;
  EventKind first_event = EventKind::DEVICE_CONNECTED, last_event = EventKind::DEVICE_CONNECTED;
};

Counts drain(Runtime& rt) {
  Counts c;
  Write w;
  while (rt.poll_write(w)) {
    ++c.writes;
    if (w.attr == Attr::command && w.value.view() == "stop") ++c.stops;
  }
  ActionResult r;
  while (rt.poll_result(r)) {
    ++c.results;
    c.last = r.outcome;
  }
  Event e;
  while (rt.poll_event(e)) {
    if (c.events++ == 0) c.first_event = e.kind;
    c.last_event = e.kind;
  }
  return c;
}

/// One tick at @p now with the positions and sensor values given.
void tick(Runtime& rt, ev3proto::Millis now, const char* pos, const char* touch, const char* us) {
  ReadPlan p;
  rt.plan_reads(p, now);
  for (std::size_t i = 0; i < p.count; ++i) {
    const Read& r = p.reads[i];
    const char* text = r.attr == Attr::position ? pos : r.dev == Dev::in1 ? touch : r.dev == Dev::in4 ? us : "8000000";
    rt.reading(r.dev, r.attr, text, now);
  }
  rt.tick(now);
}
}  // namespace

int main() {
  Runtime rt(RuntimeConfig{}, 0);
  for (std::size_t i = 0; i < 4; ++i) rt.led_present(led_dev(i), 255);
  rt.battery_present(true);
  rt.device_connected(large_motor(Dev::outB), 0);
  rt.device_connected(large_motor(Dev::outC), 0);
  rt.device_connected(sensor(Dev::in1, "lego-ev3-touch", "TOUCH", "TOUCH", "0"), 0);
  rt.device_connected(sensor(Dev::in4, "lego-ev3-us", "US-DIST-CM US-DIST-IN US-SI-CM", "US-DIST-CM", "1"), 0);
  Counts c = drain(rt);
  CHECK(c.events == 4 && rt.plugged() == (kMotors | kTouch | kUltrasonic));
  rt.led(ev3proto::Led::YELLOW_BLINK);
  CHECK(drain(rt).writes == 16);

  // drive until the bumper: the stop is written in the tick that reads the press.
  tick(rt, 1, "0", "0", "800");
  const std::string_view args[1] = {"speed=400"};
  rt.control(ev3proto::ControlKind::start, "drive", args, 1, 2);
  c = drain(rt);
  CHECK(c.writes == 4 && c.stops == 0);
  CHECK(rt.next_deadline() <= 2 + 20);
  tick(rt, 22, "8", "0", "800");
  tick(rt, 42, "16", "1", "800");
  c = drain(rt);
  CHECK(c.stops == 2 && c.last == Outcome::interrupted && c.last_event == EventKind::OBSTACLE_DETECTED);

  // The master lost while driving: the core pauses, the motors stop in that call.
  rt.control(ev3proto::ControlKind::start, "drive", args, 1, 100);
  drain(rt);
  rt.control(ev3proto::ControlKind::pause, "drive", args, 1, 120);
  CHECK(drain(rt).stops == 2);
  rt.control(ev3proto::ControlKind::resume, "drive", args, 1, 200);
  CHECK(drain(rt).writes == 4);
  rt.control(ev3proto::ControlKind::stop, "drive", args, 1, 220);
  CHECK(drain(rt).stops == 2);

  // DriveDistance to its end (positions jump to the target and stay).
  rt.run(action::single(action::drive_distance(100, 300, StopAction::hold)), 300);
  drain(rt);
  tick(rt, 320, "100", "0", "800");  // started at 16: the target is 16 + 205
  tick(rt, 340, "221", "0", "800");
  tick(rt, 360, "221", "0", "800");
  c = drain(rt);
  CHECK(c.results == 1 && c.last == Outcome::finished);

  // Garbage is an event, not a crash; unplugging a motor is critical.
  CHECK(!rt.reading(Dev::in4, Attr::value0, "\xff\xfe", 400));
  rt.device_disconnected(Dev::outC, 410);
  c = drain(rt);
  // Two events; the critical one is handled (and handed on) first.
  CHECK(c.events == 2 && c.first_event == EventKind::DEVICE_DISCONNECTED && c.last_event == EventKind::DEVICE_ERROR);
  CHECK((rt.plugged() & kMotorRight) == 0);

  // BATTERY_LOW after 3 s below 6.2 V: off, no more deadline.
  for (ev3proto::Millis t = 1000; t <= 5000; t += 1000) {
    rt.reading(Dev::battery, Attr::voltage_now, "6000000\n", t);
    rt.tick(t);
  }
  c = drain(rt);
  CHECK(c.last_event == EventKind::BATTERY_LOW && rt.off() && rt.next_deadline() == Runtime::kNever);
  CHECK(rt.dropped() == 0);
  std::printf("robot runtime, -fno-exceptions -fno-rtti: ok (sizeof(Runtime) = %zu bytes)\n", sizeof rt);
  return 0;
}
