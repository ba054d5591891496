#include "ev3io/robot_io.hpp"

namespace ev3io {

namespace robot = ev3proto::robot;
using ev3proto::Millis;

void RobotIo::scan(robot::Runtime& rt, Millis now) {
  next_scan_ = now + Ev3Devices::kScanPeriodMs;
  devices_.scan(changes_);
  if (!announced_) {
    announced_ = true;
    for (std::size_t i = 0; i < robot::kLedCount; ++i) {
      const robot::Dev led = robot::led_dev(i);
      if (devices_.led_max(led) > 0) rt.led_present(led, devices_.led_max(led));
    }
  }
  rt.battery_present(devices_.has_battery());
  for (const DeviceChange& c : changes_) {
    switch (c.kind) {
      case DeviceChange::Kind::connected: rt.device_connected(c.info, now); break;
      case DeviceChange::Kind::disconnected: rt.device_disconnected(c.info.dev, now); break;
      case DeviceChange::Kind::faulty: rt.device_faulty(c.info.dev, c.why, now); break;
    }
  }
}

void RobotIo::tick(robot::Runtime& rt, Millis now) {
  robot::ReadPlan plan;
  rt.plan_reads(plan, now);
  for (std::size_t i = 0; i < plan.count; ++i) {
    const robot::Read& r = plan.reads[i];
    if (r.dev != robot::Dev::battery && !devices_.present(r.dev)) continue;  // reported gone this tick
    const AccessResult a = devices_.read(r.dev, r.attr);
    ++stats_.reads;
    switch (a.status) {
      case Access::ok: rt.reading(r.dev, r.attr, a.text, now); break;
      case Access::gone:
        ++stats_.unplugged;
        rt.device_disconnected(r.dev, now);
        break;
      case Access::failed:
        ++stats_.failed_reads;
        rt.read_failed(r.dev, r.attr, a.err, now);
        break;
    }
  }
  rt.tick(now);
}

void RobotIo::flush(robot::Runtime& rt, Millis now) {
  robot::Write w;
  while (rt.poll_write(w)) {
    const AccessResult a = devices_.write(w.dev, w.attr, w.value.view());
    ++stats_.writes;
    if (a.status == Access::gone) {
      ++stats_.unplugged;
      if (!robot::is_led(w.dev)) rt.device_disconnected(w.dev, now);
    } else if (a.status == Access::failed) {
      ++stats_.failed_writes;
      rt.write_failed(w, a.err, now);
    }
  }
}

}  // namespace ev3io
