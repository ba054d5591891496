#include "leds.hpp"

#include <ev3proto/robot/leds.hpp>

namespace ev3agent {

namespace robot = ev3proto::robot;

LedColour colour_of(ev3proto::Led l) noexcept {
  const robot::LedColour c = robot::colour_of(l);
  return {c.red_permille / 1000.0, c.green_permille / 1000.0, c.blink};
}

Leds::Leds(std::string sysfs_root, ev3io::Logger& log) : devices_(sysfs_root), log_(log) {
  devices_.scan_leds();
  const std::string dir = sysfs_root + "/class/leds";
  if (*devices_.led_names() != '\0') {
    dir_ = dir;
    log_.log(ev3io::kVerbose, "LEDs: %s names under %s", devices_.led_names(), dir.c_str());
    return;
  }
  std::vector<std::string> names;
  if (ev3io::system_io().list(dir, names) != 0)
    log_.log(ev3io::kVerbose, "no LED directory %s: LED patterns are only logged", dir.c_str());
  else
    log_.log(ev3io::kVerbose, "no ev3dev brick-status LEDs under %s: LED patterns are only logged", dir.c_str());
}

void Leds::set(ev3proto::Led l) {
  log_.log(ev3io::kDebug, "LED %s", std::string(ev3proto::to_string(l)).c_str());
  if (dir_.empty()) return;
  robot::WriteQueue<32> writes;
  for (std::size_t i = 0; i < robot::kLedCount; ++i) {
    const robot::Dev led = robot::led_dev(i);
    if (devices_.led_max(led) > 0) robot::led_writes(l, led, devices_.led_max(led), writes);
  }
  for (robot::Write w; writes.pop(w);) {
    const ev3io::AccessResult r = devices_.write(w.dev, w.attr, w.value.view());
    if (r.status != ev3io::Access::ok && !warned_) {
      warned_ = true;
      log_.log(ev3io::kVerbose, "cannot write %s/%s (%s); further LED errors not logged", devices_.dir(w.dev).c_str(),
               std::string(robot::to_string(w.attr)).c_str(), std::string(robot::errno_name(r.err)).c_str());
    }
  }
}

}  // namespace ev3agent
