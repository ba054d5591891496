#include "ev3io/devices.hpp"

#include <algorithm>
#include <cerrno>

namespace ev3io {

namespace robot = ev3proto::robot;
using robot::Attr;
using robot::Dev;
using robot::DeviceClass;

const char* const kLedNamesStretch[4] = {"led0:red:brick-status", "led0:green:brick-status", "led1:red:brick-status",
                                         "led1:green:brick-status"};
const char* const kLedNamesJessie[4] = {"ev3:left:red:ev3dev", "ev3:left:green:ev3dev", "ev3:right:red:ev3dev",
                                        "ev3:right:green:ev3dev"};
const char* const kBatteryNames[2] = {"lego-ev3-battery", "legoev3-battery"};

namespace {
/// "reading max_speed failed (EIO)".
std::string failed(const char* what, Attr a, const AccessResult& r) {
  return std::string(what) + " " + std::string(robot::to_string(a)) + " failed (" + std::string(robot::errno_name(r.err)) + ")";
}
}  // namespace

Ev3Devices::Ev3Devices(std::string sysfs_root, SysfsIo& io) : root_(std::move(sysfs_root)), io_(io) {}

int Ev3Devices::led_max(Dev led) const noexcept {
  return robot::is_led(led) ? slots_[robot::index(led)].max_brightness : 0;
}

std::string Ev3Devices::dir(Dev d) const {
  const Slot& s = slots_[robot::index(d)];
  return s.dev != nullptr ? s.dev->dir() : std::string();
}

std::size_t Ev3Devices::calls() const noexcept {
  std::size_t n = closed_calls_;
  for (const Slot& s : slots_)
    if (s.dev != nullptr) n += s.dev->calls();
  return n;
}

void Ev3Devices::drop(Dev d) {
  Slot& s = slots_[robot::index(d)];
  if (s.dev != nullptr) {
    s.dev->close_all();
    closed_calls_ += s.dev->calls();
  }
  s.dev.reset();
  s.name.clear();
}

void Ev3Devices::find_leds() {
  const std::string dir = root_ + "/class/leds";
  std::vector<std::string> names;
  if (io_.list(dir, names) != 0) return;
  for (const char* const* set : {kLedNamesStretch, kLedNamesJessie}) {
    bool any = false;
    for (int i = 0; i < 4; ++i) {
      if (std::find(names.begin(), names.end(), set[i]) == names.end()) continue;
      auto dev = std::make_unique<SysfsDevice>(io_, dir + "/" + set[i], true);
      const AccessResult r = dev->read(Attr::max_brightness);
      std::int32_t max = 0;
      if (r.status != Access::ok || !robot::parse_int(r.text, max) || max <= 0) max = 255;  // the EV3's LEDs
      Slot& s = slots_[robot::index(robot::led_dev(static_cast<std::size_t>(i)))];
      s.dev = std::move(dev);
      s.cls = DeviceClass::leds;
      s.name = set[i];
      s.max_brightness = max;
      any = true;
    }
    if (any) {
      led_generation_ = set == kLedNamesStretch ? "stretch" : "jessie";
      return;
    }
  }
}

void Ev3Devices::find_battery() {
  const std::string dir = root_ + "/class/power_supply";
  std::vector<std::string> names;
  if (io_.list(dir, names) != 0) return;
  for (const char* n : kBatteryNames) {
    if (std::find(names.begin(), names.end(), n) == names.end()) continue;
    Slot& s = slots_[robot::index(Dev::battery)];
    s.dev = std::make_unique<SysfsDevice>(io_, dir + "/" + n);
    s.cls = DeviceClass::power_supply;
    s.name = n;
    return;
  }
}

void Ev3Devices::scan_leds() {
  if (leds_looked_) return;
  leds_looked_ = true;
  find_leds();
}

void Ev3Devices::scan(std::vector<DeviceChange>& changes) {
  changes.clear();
  scan_leds();
  if (!has_battery()) find_battery();
  scan_class(DeviceClass::tacho_motor, changes);
  scan_class(DeviceClass::lego_sensor, changes);
}

void Ev3Devices::scan_class(DeviceClass cls, std::vector<DeviceChange>& changes) {
  const std::string dir = root_ + "/class/" + std::string(robot::to_string(cls));
  std::vector<std::string> names;
  // No class directory (no ev3dev here): no devices.
  if (io_.list(dir, names) == 0) classes_found_ = true;
  const std::size_t first = cls == DeviceClass::tacho_motor ? 0 : 4;
  // Known devices: still listed, and still answering with the same address?
  for (std::size_t p = first; p < first + 4; ++p) {
    Slot& s = slots_[p];
    if (s.dev == nullptr) continue;
    bool gone = std::find(names.begin(), names.end(), s.name) == names.end();
    if (!gone) {
      const AccessResult r = s.dev->read(Attr::address);
      Dev d{};
      gone = r.status == Access::gone || (r.status == Access::ok && (!robot::parse_address(r.text, d) || robot::index(d) != p));
    }
    if (!gone) continue;
    DeviceChange c;
    c.kind = DeviceChange::Kind::disconnected;
    c.info.dev = static_cast<Dev>(p);
    c.info.cls = cls;
    c.dir = s.dev->dir();
    drop(static_cast<Dev>(p));
    changes.push_back(std::move(c));
  }
  // Forget ignored entries that went away (a new device may come back under that name).
  for (auto it = ignored_.begin(); it != ignored_.end();) {
    const std::string prefix = std::string(robot::to_string(cls)) + "/";
    if (it->rfind(prefix, 0) == 0 && std::find(names.begin(), names.end(), it->substr(prefix.size())) == names.end())
      it = ignored_.erase(it);
    else
      ++it;
  }
  // New names.
  std::sort(names.begin(), names.end());
  for (const std::string& n : names) {
    const std::string key = std::string(robot::to_string(cls)) + "/" + n;
    if (ignored_.count(key) != 0) continue;
    bool known = false;
    for (std::size_t p = first; p < first + 4; ++p) known = known || (slots_[p].dev != nullptr && slots_[p].name == n);
    if (known) continue;
    auto dev = std::make_unique<SysfsDevice>(io_, dir + "/" + n);
    const AccessResult a = dev->read(Attr::address);
    if (a.status == Access::gone) continue;  // vanished while we looked
    Dev port{};
    if (a.status != Access::ok || !robot::parse_address(a.text, port) || robot::is_out_port(port) != (first == 0)) {
      ignored_.insert(key);
      ignored_list_.push_back(dir + "/" + n + (a.status == Access::ok ? " (address '" + std::string(robot::chomp(a.text)) + "')"
                                                                       : " (" + failed("reading", Attr::address, a) + ")"));
      closed_calls_ += dev->calls();
      continue;
    }
    Slot& s = slots_[robot::index(port)];
    if (s.dev != nullptr) {  // two devices listed on one port: keep the one in use
      ignored_.insert(key);
      ignored_list_.push_back(dir + "/" + n + " (a second device on " + std::string(robot::to_string(port)) + ")");
      closed_calls_ += dev->calls();
      continue;
    }
    DeviceChange c = describe(cls, port, *dev);
    c.dir = dir + "/" + n;
    if (c.kind == DeviceChange::Kind::connected) {
      s.dev = std::move(dev);
      s.cls = cls;
      s.name = n;
    } else {
      if (c.kind == DeviceChange::Kind::disconnected) continue;  // vanished while we looked
      ignored_.insert(key);
      closed_calls_ += dev->calls();
    }
    changes.push_back(std::move(c));
  }
}

DeviceChange Ev3Devices::describe(DeviceClass cls, Dev port, SysfsDevice& dev) {
  DeviceChange c;
  c.info.dev = port;
  c.info.cls = cls;
  // The texts, each read once; a read that fails makes the device faulty (gone: it vanished).
  std::string texts[6];
  const Attr motor_attrs[] = {Attr::driver_name, Attr::max_speed, Attr::count_per_rot, Attr::commands, Attr::stop_actions};
  const Attr sensor_attrs[] = {Attr::driver_name, Attr::modes, Attr::mode, Attr::decimals, Attr::num_values, Attr::units};
  const Attr* attrs = cls == DeviceClass::tacho_motor ? motor_attrs : sensor_attrs;
  const std::size_t count = cls == DeviceClass::tacho_motor ? 5 : 6;
  for (std::size_t i = 0; i < count; ++i) {
    const AccessResult r = dev.read(attrs[i]);
    if (r.status == Access::gone) {
      c.kind = DeviceChange::Kind::disconnected;
      return c;
    }
    if (r.status != Access::ok) {
      c.kind = DeviceChange::Kind::faulty;
      c.why = failed("reading", attrs[i], r);
      return c;
    }
    texts[i] = std::string(robot::chomp(r.text));
  }
  c.info.driver = robot::parse_driver(texts[0]);
  c.info.driver_name = robot::Text<24>(texts[0]);
  robot::ReasonText why;
  bool ok = false;
  if (cls == DeviceClass::tacho_motor) {
    const robot::MotorTexts t{texts[0], texts[1], texts[2], texts[3], texts[4]};
    ok = robot::parse_motor_info(t, c.info.motor, why);
  } else {
    const robot::SensorTexts t{texts[0], texts[1], texts[2], texts[3], texts[4], texts[5]};
    ok = robot::parse_sensor_info(t, c.info.sensor, why);
  }
  if (!ok) {
    c.kind = DeviceChange::Kind::faulty;
    c.why = std::string(why.view());
  }
  return c;
}

template <typename Op>
AccessResult Ev3Devices::access(Dev d, Op op) {
  Slot& s = slots_[robot::index(d)];
  if (s.dev == nullptr) {
    AccessResult r;
    r.status = Access::gone;
    r.err = ENODEV;
    return r;
  }
  const AccessResult r = op(*s.dev);
  if (r.status == Access::gone && robot::is_port(d)) drop(d);  // unplugged (an LED attribute can come back)
  return r;
}

AccessResult Ev3Devices::read(Dev d, Attr a) {
  return access(d, [a](SysfsDevice& dev) { return dev.read(a); });
}

AccessResult Ev3Devices::write(Dev d, Attr a, std::string_view value) {
  return access(d, [a, value](SysfsDevice& dev) { return dev.write(a, value); });
}

}  // namespace ev3io
