#include "ev3sim/robot.hpp"

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>

namespace ev3sim {

namespace {

constexpr double kGravity = 981.0;  // cm/s^2

// The per-generation names and places of things (tests/data/ev3dev/README.md, "Layout").
struct Layout {
  const char* ports_root;     // where the port directories live
  bool port_in_own_dir;       // stretch: ev3-ports/ev3-ports:outB/lego-port/port5
  const char* address_prefix; // "ev3-ports:" or ""
  const char* leds_parent;    // the LEDs' parent device
  const char* led_names[4];   // left red, left green, right red, right green
  const char* triggers;       // after "none"
  const char* battery_parent;
  const char* battery_name;
  unsigned technology_mode;
  const char* max_design;
  const char* min_design;
  bool voltage_now_first;     // uevent: VOLTAGE_NOW before the design voltages (stretch)
};

const Layout kStretch{
    "devices/platform/ev3-ports", true, "ev3-ports:", "devices/platform/leds",
    {"led0:red:brick-status", "led0:green:brick-status", "led1:red:brick-status", "led1:green:brick-status"},
    "kbd-scrolllock kbd-numlock kbd-capslock kbd-kanalock kbd-shiftlock kbd-altgrlock kbd-ctrllock "
    "kbd-altlock kbd-shiftllock kbd-shiftrlock kbd-ctrlllock kbd-ctrlrlock mmc0 timer heartbeat "
    "default-on transient lego-ev3-battery-charging-or-full lego-ev3-battery-charging "
    "lego-ev3-battery-full lego-ev3-battery-charging-blink-full-solid rfkill-any rfkill0",
    "devices/platform/battery", "lego-ev3-battery", 0644, "90000000", "48000000", true};

const Layout kJessie{
    "devices/platform/legoev3-ports", false, "", "devices/platform/leds_pwm",
    {"ev3:left:red:ev3dev", "ev3:left:green:ev3dev", "ev3:right:red:ev3dev", "ev3:right:green:ev3dev"},
    "mmc0 timer heartbeat default-on transient legoev3-battery-charging-or-full "
    "legoev3-battery-charging legoev3-battery-full legoev3-battery-charging-blink-full-solid rfkill0",
    "devices/platform/legoev3-battery", "legoev3-battery", 0444, "7500000", "6200000", false};

const Layout& layout(Generation g) { return g == Generation::Stretch ? kStretch : kJessie; }

ReadResult text(std::string s) { return {0, std::move(s)}; }
ReadResult number(long long v) { return {0, std::to_string(v) + "\n"}; }

// Writing an action to a device's uevent file makes the kernel emit that uevent.
WriteResult uevent_write(std::string_view data) {
  static const char* const kActions[] = {"add", "remove", "change", "move", "online", "offline", "bind", "unbind"};
  const auto w = split_words(data.substr(0, data.find('\n')));
  if (!w.empty())
    for (const char* a : kActions)
      if (w[0] == a) return {};
  return {EINVAL, 0};
}

}  // namespace

namespace {
// The EV3's ports in the order the lego-port class numbers them: in1..in4 register first.
const char* const kPorts[] = {"in1", "in2", "in3", "in4", "outA", "outB", "outC", "outD"};
}  // namespace

int port_index(const std::string& port) {
  for (int i = 0; i < 8; ++i)
    if (port == kPorts[i]) return i;
  return -1;
}

int Led::shown(SimTime now) const {
  if (trigger == "default-on") return 255;
  if (trigger == "timer") {
    const SimTime period = static_cast<SimTime>(delay_on) + delay_off;
    if (period <= 0) return brightness;
    const SimTime phase = ((now - trigger_since) / 1000) % period;
    return phase < delay_on ? brightness : 0;
  }
  return brightness;
}

Robot::Robot(RobotConfig cfg) : cfg_(std::move(cfg)) {
  pose_ = cfg_.start;
  heading_total_ = rad2deg(cfg_.start.heading);
  full_volts_ = cfg_.battery.full_volts;
  volts_ = full_volts_ - cfg_.battery.idle_amps * cfg_.battery.resistance;
  amps_ = cfg_.battery.idle_amps;
  path_.push_back(pose_.p);
  build_static_tree();
  const ModelA& m = cfg_.model;
  // Model A, plugged in the order a brick detects it after boot (motor0, motor1, sensor0..2).
  plug(m.left, "lego-ev3-l-motor");
  plug(m.right, "lego-ev3-l-motor");
  plug(m.touch, "lego-ev3-touch");
  plug(m.colour_port, "lego-ev3-color");
  plug(m.ultrasonic_port, "lego-ev3-us");
}

std::string Robot::address(const std::string& port) const {
  return std::string(layout(cfg_.gen).address_prefix) + port;
}

void Robot::add_common(const std::string& dir, const std::string& subsystem_class,
                       const std::string& device_dir, std::function<std::string()> uevent) {
  tree_.add_relative_link(dir + "/device", device_dir);
  tree_.add_relative_link(dir + "/subsystem", "class/" + subsystem_class);
  tree_.add_file(dir + "/uevent", 0644, [uevent] { return text(uevent()); }, uevent_write);
  // The runtime-PM group (CONFIG_PM without autosuspend).
  auto control = std::make_shared<std::string>("auto");
  tree_.add_file(dir + "/power/autosuspend_delay_ms", 0644, [] { return ReadResult{EIO, {}}; },
                 [](std::string_view) { return WriteResult{EIO, 0}; });
  tree_.add_file(
      dir + "/power/control", 0644, [control] { return text(*control + "\n"); },
      [control](std::string_view d) {
        if (sysfs_streq(d, "auto")) *control = "auto";
        else if (sysfs_streq(d, "on")) *control = "on";
        else return WriteResult{EINVAL, 0};
        return WriteResult{};
      });
  tree_.add_file(dir + "/power/runtime_active_time", 0444, [] { return text("0\n"); }, nullptr);
  tree_.add_file(dir + "/power/runtime_status", 0444, [] { return text("unsupported\n"); }, nullptr);
  tree_.add_file(dir + "/power/runtime_suspended_time", 0444, [] { return text("0\n"); }, nullptr);
}

void Robot::build_static_tree() {
  const Layout& lay = layout(cfg_.gen);
  tree_.mkdirs("class/lego-sensor");
  tree_.mkdirs("class/tacho-motor");
  if (cfg_.gen == Generation::Stretch) {
    add_board_info();
    add_lego_ports();
  }
  for (int i = 0; i < 4; ++i) add_led(i);
  // The battery.
  const std::string dir = std::string(lay.battery_parent) + "/power_supply/" + lay.battery_name;
  tree_.add_relative_link(std::string("class/power_supply/") + lay.battery_name, dir);
  const Generation gen = cfg_.gen;
  auto technology = std::make_shared<std::string>("Unknown");
  const Layout* L = &lay;
  add_common(dir, "power_supply", lay.battery_parent, [this, technology, gen, L] {
    const Layout& l = *L;
    const std::string v = std::to_string(std::llround(volts_ * 1e6));
    const std::string c = std::to_string(std::llround(amps_ * 1e6));
    std::string s = std::string("POWER_SUPPLY_NAME=") + l.battery_name + "\nPOWER_SUPPLY_TECHNOLOGY=" + *technology + "\n";
    const std::string design = std::string("POWER_SUPPLY_VOLTAGE_MAX_DESIGN=") + l.max_design +
                               "\nPOWER_SUPPLY_VOLTAGE_MIN_DESIGN=" + l.min_design + "\n";
    const std::string now = "POWER_SUPPLY_VOLTAGE_NOW=" + v + "\n";
    s += gen == Generation::Stretch ? now + design : design + now;
    return s + "POWER_SUPPLY_CURRENT_NOW=" + c + "\nPOWER_SUPPLY_SCOPE=System\n";
  });
  tree_.add_file(dir + "/current_now", 0444, [this] { return number(std::llround(amps_ * 1e6)); }, nullptr);
  tree_.add_file(dir + "/scope", 0444, [] { return text("System\n"); }, nullptr);
  WriteFn tech_write = nullptr;
  if (lay.technology_mode & 0200)
    tech_write = [technology](std::string_view d) {
      // The stretch driver lets the unknown chemistry of AA cells be set to NiMH (and back).
      if (sysfs_streq(d, "Unknown")) *technology = "Unknown";
      else if (sysfs_streq(d, "NiMH")) *technology = "NiMH";
      else return WriteResult{EINVAL, 0};
      return WriteResult{};
    };
  tree_.add_file(dir + "/technology", lay.technology_mode, [technology] { return text(*technology + "\n"); },
                 tech_write);
  tree_.add_file(dir + "/type", 0444, [] { return text("Battery\n"); }, nullptr);
  tree_.add_file(dir + "/voltage_max_design", 0444, [L] { return text(std::string(L->max_design) + "\n"); }, nullptr);
  tree_.add_file(dir + "/voltage_min_design", 0444, [L] { return text(std::string(L->min_design) + "\n"); }, nullptr);
  tree_.add_file(dir + "/voltage_now", 0444, [this] { return number(std::llround(volts_ * 1e6)); }, nullptr);
}

// The board-info class (stretch): the brick's identity in board0's uevent, which libraries read to
// tell an EV3 from other boards. The serial number is the brick's Bluetooth address on a brick;
// here 0016530 and the robot's seed in five digits, so robots of one run differ.
void Robot::add_board_info() {
  const std::string dir = "devices/virtual/board-info/board0";
  char serial[16];
  std::snprintf(serial, sizeof serial, "0016530%05llu", static_cast<unsigned long long>(cfg_.seed % 100000));
  const std::string uevent = std::string("BOARD_INFO_HW_REV=7\nBOARD_INFO_MODEL=LEGO MINDSTORMS EV3\n") +
                             "BOARD_INFO_ROM_REV=6\nBOARD_INFO_SERIAL_NUM=" + serial + "\nBOARD_INFO_TYPE=main\n";
  tree_.add_relative_link("class/board-info/board0", dir);
  tree_.add_relative_link(dir + "/subsystem", "class/board-info");
  tree_.add_file(dir + "/uevent", 0644, [uevent] { return text(uevent); }, uevent_write);
}

// The lego-port class (stretch): a port device per input and output port, the parent of the
// device plugged into it. Only the ports' auto mode is emulated: `mode` reads and takes `auto`,
// another of the port's modes and `set_device` are refused with EOPNOTSUPP (an unknown mode with
// EINVAL, as the driver does); `status` says what auto detection found.
void Robot::add_lego_ports() {
  const Layout& lay = layout(cfg_.gen);
  for (int i = 0; i < 8; ++i) {
    const std::string port = kPorts[i];
    const bool input = i < 4;
    const std::string addr = address(port);
    const std::string parent = std::string(lay.ports_root) + "/" + addr;
    const std::string dir = parent + "/lego-port/port" + std::to_string(i);
    const std::string driver = input ? "ev3-input-port" : "ev3-output-port";
    const std::string modes = input ? "auto nxt-analog nxt-color nxt-i2c other-i2c ev3-analog ev3-uart other-uart raw"
                                    : "auto tacho-motor dc-motor led raw";
    tree_.add_relative_link("class/lego-port/port" + std::to_string(i), dir);
    add_common(dir, "lego-port", parent,
               [driver, addr] { return "LEGO_DRIVER_NAME=" + driver + "\nLEGO_ADDRESS=" + addr + "\n"; });
    tree_.add_file(dir + "/address", 0444, [addr] { return text(addr + "\n"); }, nullptr);
    tree_.add_file(dir + "/driver_name", 0444, [driver] { return text(driver + "\n"); }, nullptr);
    tree_.add_file(dir + "/modes", 0444, [modes] { return text(modes + "\n"); }, nullptr);
    tree_.add_file(dir + "/mode", 0644, [] { return text("auto\n"); }, [modes](std::string_view d) {
      for (const std::string& m : split_words(modes))
        if (sysfs_streq(d, m)) return WriteResult{m == "auto" ? 0 : EOPNOTSUPP, 0};
      return WriteResult{EINVAL, 0};
    });
    tree_.add_file(dir + "/set_device", 0200, nullptr, [](std::string_view) { return WriteResult{EOPNOTSUPP, 0}; });
    tree_.add_file(dir + "/status", 0444, [this, port, input] {
      const std::string d = plugged(port);
      if (d.empty()) return text(input ? "no-sensor\n" : "no-motor\n");
      if (!input) return text("tacho-motor\n");
      const SensorDef* s = sensor_def(d);  // the touch sensor is EV3/Analog, the others EV3/UART
      return text(s != nullptr && s->kind == SensorKind::Touch ? "ev3-analog\n" : "ev3-uart\n");
    }, nullptr);
    tree_.give_to_ev3dev_group(tree_.resolve(dir));
  }
}

// --- LEDs ------------------------------------------------------------------------------------

void Robot::add_led(int i) {
  const Layout& lay = layout(cfg_.gen);
  Led& led = leds_[static_cast<std::size_t>(i)];
  led.name = lay.led_names[i];
  led.brightness = led.name.find("green") != std::string::npos ? 255 : 0;  // brickman's solid green
  const std::string dir = std::string(lay.leds_parent) + "/leds/" + led.name;
  led_dirs_[static_cast<std::size_t>(i)] = dir;
  tree_.add_relative_link("class/leds/" + led.name, dir);
  add_common(dir, "leds", lay.leds_parent, [] { return std::string(); });
  tree_.add_file(
      dir + "/brightness", 0644, [this, i] { return number(leds_[static_cast<std::size_t>(i)].shown(now_)); },
      [this, i](std::string_view d) {
        long long v = 0;
        if (int e = parse_kernel_int(d, 0, LLONG_MAX, v)) return WriteResult{e == ERANGE ? EINVAL : e, 0};
        // Brightness 0 also removes the trigger (led_trigger_remove), as the LED class does.
        if (v == 0) set_led_trigger(i, "none");
        leds_[static_cast<std::size_t>(i)].brightness = static_cast<int>(std::min<long long>(v, 255));
        return WriteResult{};
      });
  tree_.add_file(dir + "/max_brightness", 0444, [] { return text("255\n"); }, nullptr);
  tree_.add_file(
      dir + "/trigger", 0644,
      [this, i, L = &lay] {
        const std::string cur = leds_[static_cast<std::size_t>(i)].trigger;
        std::string s;
        for (const std::string& t : split_words(std::string("none ") + L->triggers))
          s += (s.empty() ? "" : " ") + (t == cur ? "[" + t + "]" : t);
        return text(s + "\n");
      },
      [this, i, L = &lay](std::string_view d) {
        for (const std::string& t : split_words(std::string("none ") + L->triggers))
          if (sysfs_streq(d, t)) {
            set_led_trigger(i, t);
            return WriteResult{};
          }
        return WriteResult{EINVAL, 0};
      });
  tree_.give_to_ev3dev_group(tree_.resolve(dir));
}

void Robot::set_led_trigger(int i, const std::string& trigger) {
  Led& led = leds_[static_cast<std::size_t>(i)];
  const std::string& dir = led_dirs_[static_cast<std::size_t>(i)];
  const bool was_timer = led.trigger == "timer";
  led.trigger = trigger;
  led.trigger_since = now_;
  if (trigger == "timer") {
    if (led.brightness == 0) led.brightness = 255;  // blinking at the LED's full brightness
    if (!was_timer) {
      led.delay_on = led.delay_off = 500;  // ledtrig-timer's default period
      for (const char* which : {"delay_on", "delay_off"}) {
        const bool on = std::string(which) == "delay_on";
        tree_.add_file(
            dir + "/" + which, 0644,
            [this, i, on] {
              const Led& l = leds_[static_cast<std::size_t>(i)];
              return number(on ? l.delay_on : l.delay_off);
            },
            [this, i, on](std::string_view d) {
              long long v = 0;
              if (int e = parse_kernel_int(d, 0, LLONG_MAX, v)) return WriteResult{e == ERANGE ? EINVAL : e, 0};
              Led& l = leds_[static_cast<std::size_t>(i)];
              (on ? l.delay_on : l.delay_off) = static_cast<int>(std::min<long long>(v, INT_MAX));
              l.trigger_since = now_;
              return WriteResult{};
            });
        tree_.give_to_ev3dev_group(tree_.resolve(dir + "/" + which));  // the new file only: chmods stay
      }
    }
  } else if (was_timer) {
    for (const char* which : {"delay_on", "delay_off"})
      if (Ino n = tree_.resolve(dir + "/" + which)) tree_.remove(n);
  }
}

// --- devices ---------------------------------------------------------------------------------

Robot::Device* Robot::device(const std::string& port) {
  auto it = devices_.find(port);
  return it == devices_.end() ? nullptr : &it->second;
}

std::string Robot::plugged(const std::string& port) const {
  auto it = devices_.find(port);
  return it == devices_.end() ? std::string() : it->second.driver;
}

TachoMotor* Robot::motor(const std::string& port) {
  Device* d = device(port);
  return d ? d->motor.get() : nullptr;
}

Sensor* Robot::sensor(const std::string& port) {
  Device* d = device(port);
  return d ? d->sensor.get() : nullptr;
}

std::string Robot::class_path(const std::string& port) const {
  auto it = devices_.find(port);
  return it == devices_.end() ? std::string() : it->second.class_link;
}

std::string Robot::plug(const std::string& port, const std::string& driver) {
  const int index = port_index(port);
  if (index < 0) return "unknown port '" + port + "' (in1..in4, outA..outD)";
  if (devices_.count(port)) return "port " + port + " already has " + devices_[port].driver;
  const MotorDef* md = motor_def(driver);
  const SensorDef* sd = sensor_def(driver);
  const bool output = port.rfind("out", 0) == 0;
  if (!md && !sd) return "unknown driver '" + driver + "'";
  if (md && !output) return "a motor goes into an output port (outA..outD), not " + port;
  if (sd && output) return "a sensor goes into an input port (in1..in4), not " + port;

  const Layout& lay = layout(cfg_.gen);
  std::string port_dir = lay.ports_root;
  if (lay.port_in_own_dir) port_dir += "/" + address(port);
  port_dir += "/lego-port/port" + std::to_string(index);
  Device d;
  d.port = port;
  d.driver = driver;
  d.dir = port_dir + "/" + address(port) + ":" + driver;
  const std::string cls = md ? "tacho-motor" : "lego-sensor";
  const std::string name = md ? "motor" + std::to_string(next_motor_++) : "sensor" + std::to_string(next_sensor_++);
  d.class_dir = d.dir + "/" + cls + "/" + name;
  d.class_link = "class/" + cls + "/" + name;
  if (md) d.motor = std::make_unique<TachoMotor>(*md);
  else d.sensor = std::make_unique<Sensor>(*sd, cfg_.gen, cfg_.seed * 1000003u + ++plugs_);
  auto [it, inserted] = devices_.emplace(port, std::move(d));
  Device& dev = it->second;
  last_driver_[port] = driver;
  tree_.add_relative_link(dev.class_link, dev.class_dir);
  const std::string addr = address(port);
  add_common(dev.class_dir, cls, dev.dir, [driver, addr] {
    return "LEGO_DRIVER_NAME=" + driver + "\nLEGO_ADDRESS=" + addr + "\n";
  });
  tree_.add_file(dev.class_dir + "/address", 0444, [addr] { return text(addr + "\n"); }, nullptr);
  tree_.add_file(dev.class_dir + "/driver_name", 0444, [driver] { return text(driver + "\n"); }, nullptr);
  add_device_files(dev);
  tree_.give_to_ev3dev_group(tree_.resolve(dev.class_dir));
  if (dev.motor) {
    dev.state = tree_.resolve(dev.class_dir + "/state");
    dev.last_state = dev.motor->state();
  }
  return {};
}

namespace {

struct Attr {
  const char* name;
  unsigned mode;
  std::uint32_t size;  // st_size: 4096 for text attributes, the buffer for binary ones
};

// The tacho-motor class's attributes (rotation motors) and the lego-sensor class's.
const Attr kMotorAttrs[] = {
    {"command", 0200, 4096},       {"commands", 0444, 4096},     {"count_per_rot", 0444, 4096},
    {"duty_cycle", 0444, 4096},    {"duty_cycle_sp", 0644, 4096}, {"hold_pid/Kd", 0644, 4096},
    {"hold_pid/Ki", 0644, 4096},   {"hold_pid/Kp", 0644, 4096},  {"max_speed", 0444, 4096},
    {"polarity", 0644, 4096},      {"position", 0644, 4096},     {"position_sp", 0644, 4096},
    {"ramp_down_sp", 0644, 4096},  {"ramp_up_sp", 0644, 4096},   {"speed", 0444, 4096},
    {"speed_pid/Kd", 0644, 4096},  {"speed_pid/Ki", 0644, 4096}, {"speed_pid/Kp", 0644, 4096},
    {"speed_sp", 0644, 4096},      {"state", 0444, 4096},        {"stop_action", 0644, 4096},
    {"stop_actions", 0444, 4096},  {"time_sp", 0644, 4096},
};
const Attr kSensorAttrs[] = {
    {"bin_data", 0444, 32},     {"bin_data_format", 0444, 4096}, {"command", 0200, 4096},
    {"commands", 0444, 4096},   {"decimals", 0444, 4096},        {"direct", 0644, 255},
    {"fw_version", 0444, 4096}, {"mode", 0644, 4096},            {"modes", 0444, 4096},
    {"num_values", 0444, 4096}, {"poll_ms", 0644, 4096},         {"text_value", 0444, 4096},
    {"units", 0444, 4096},      {"value0", 0444, 4096},          {"value1", 0444, 4096},
    {"value2", 0444, 4096},     {"value3", 0444, 4096},          {"value4", 0444, 4096},
    {"value5", 0444, 4096},     {"value6", 0444, 4096},          {"value7", 0444, 4096},
};

}  // namespace

ReadResult Robot::read_attr(const std::string& port, const std::string& name) {
  if (TachoMotor* m = motor(port)) return m->read(name);
  if (Sensor* s = sensor(port)) return s->read(name);
  return {ENODEV, {}};
}

WriteResult Robot::write_attr(const std::string& port, const std::string& name, std::string_view data) {
  if (TachoMotor* m = motor(port)) {
    const WriteResult r = m->write(name, data, now_);
    notify_state_changes();  // a command changes the state at once (running, or stopped)
    return r;
  }
  if (Sensor* s = sensor(port)) return s->write(name, data, now_);
  return {ENODEV, 0};
}

void Robot::add_device_files(Device& d) {
  const std::string port = d.port;
  for (const Attr& a : d.motor ? std::vector<Attr>(std::begin(kMotorAttrs), std::end(kMotorAttrs))
                               : std::vector<Attr>(std::begin(kSensorAttrs), std::end(kSensorAttrs))) {
    const std::string name = a.name;
    ReadFn r = nullptr;
    WriteFn w = nullptr;
    if (a.mode & 0444) r = [this, port, name] { return read_attr(port, name); };
    if (a.mode & 0200) w = [this, port, name](std::string_view data) { return write_attr(port, name, data); };
    tree_.add_file(d.class_dir + "/" + a.name, a.mode, std::move(r), std::move(w), a.size);
  }
}

std::string Robot::unplug(const std::string& port) {
  if (port_index(port) < 0) return "unknown port '" + port + "' (in1..in4, outA..outD)";
  Device* d = device(port);
  if (!d) return "nothing is plugged into " + port;
  if (Ino n = tree_.resolve(d->class_link)) tree_.remove(n);
  if (Ino n = tree_.resolve(d->dir)) tree_.remove(n);
  devices_.erase(port);
  return {};
}

std::string Robot::replug(const std::string& port) {
  if (port_index(port) < 0) return "unknown port '" + port + "' (in1..in4, outA..outD)";
  if (devices_.count(port)) return "port " + port + " is not unplugged";
  auto it = last_driver_.find(port);
  if (it == last_driver_.end()) return "nothing was ever plugged into " + port;
  return plug(port, it->second);
}

bool Robot::ultrasonic_emitting() const {
  for (const auto& [port, d] : devices_)
    if (d.sensor && d.sensor->def().kind == SensorKind::Ultrasonic &&
        std::string(d.sensor->mode().name) != "US-LISTEN")
      return true;
  return false;
}

// --- battery ---------------------------------------------------------------------------------

void Robot::set_battery_volts(double v) {
  // Move the open-circuit curve so that it reads v now.
  const BatteryModel& b = cfg_.battery;
  const double drop = (full_volts_ - b.empty_volts) * used_ah_ * 1000.0 / b.capacity_mah;
  full_volts_ = v + drop;
  volts_ = std::max(0.0, v - amps_ * b.resistance);
}

// --- body ------------------------------------------------------------------------------------

void Robot::set_pose(const Pose& p) {
  heading_total_ += rad2deg(wrap_angle(p.heading - pose_.heading));
  pose_ = p;
  v_ = w_ = 0;
  path_.push_back(p.p);
}

Convex Robot::footprint(const Pose& p) const {
  const ModelA& m = cfg_.model;
  return {p.to_world({m.body_rear, -m.body_half_width}), p.to_world({m.body_front, -m.body_half_width}),
          p.to_world({m.body_front, m.body_half_width}), p.to_world({m.body_rear, m.body_half_width})};
}

Convex Robot::bumper_zone() const {
  const ModelA& m = cfg_.model;
  const double f0 = m.body_front, f1 = m.body_front + m.bumper_travel, w = m.bumper_half_width;
  return {pose_.to_world({f0, -w}), pose_.to_world({f1, -w}), pose_.to_world({f1, w}), pose_.to_world({f0, w})};
}

Pose Robot::propose(double dt, SimTime now) {
  const ModelA& m = cfg_.model;
  dl_ = dr_ = 0;
  double counts_per_rot = 360;
  for (auto& [port, d] : devices_) {
    if (!d.motor) continue;
    const double delta = d.motor->propose(dt, volts_, now);
    if (port == m.left) dl_ = delta, counts_per_rot = d.motor->def().count_per_rot;
    if (port == m.right) dr_ = delta, counts_per_rot = d.motor->def().count_per_rot;
  }
  auto rim = [&](const std::string& port, double delta) {
    TachoMotor* mo = motor(port);
    return mo ? delta * mo->polarity_sign() / counts_per_rot * kPi * m.wheel_diameter : 0.0;
  };
  const double sl = rim(m.left, dl_), sr = rim(m.right, dr_);
  // The body follows the wheels as far as the tyres' grip allows (it slides otherwise).
  const double vw = (sl + sr) / 2 / dt, ww = (sr - sl) / m.wheel_base / dt;
  const double amax = m.traction * kGravity * dt;
  const double alpha = amax / (m.wheel_base / 2);
  v_ += std::clamp(vw - v_, -amax, amax);
  w_ += std::clamp(ww - w_, -alpha, alpha);
  const double mid = pose_.heading + w_ * dt / 2;
  candidate_.p = pose_.p + Vec2{std::cos(mid), std::sin(mid)} * (v_ * dt);
  candidate_.heading = wrap_angle(pose_.heading + w_ * dt);
  return candidate_;
}

void Robot::commit(double fraction, bool blocked, SimTime now, double dt) {
  const Vec2 before = pose_.p;
  pose_.p = pose_.p + (candidate_.p - pose_.p) * fraction;
  pose_.heading = wrap_angle(pose_.heading + wrap_angle(candidate_.heading - pose_.heading) * fraction);
  heading_total_ += rad2deg(w_ * dt * fraction);
  travelled_ += length(pose_.p - before);
  if (blocked) v_ = w_ = 0;
  const ModelA& m = cfg_.model;
  double amps = cfg_.battery.idle_amps;
  for (auto& [port, d] : devices_) {
    if (!d.motor) continue;
    const bool wheel = port == m.left || port == m.right;
    const double delta = port == m.left ? dl_ : port == m.right ? dr_ : 0.0;
    if (wheel) d.motor->commit(delta * (blocked ? fraction : 1.0), blocked, now);
    else d.motor->commit(d.motor->speed() * dt, false, now);
    amps += d.motor->current();
  }
  if (length(pose_.p - path_.back()) >= 0.5) path_.push_back(pose_.p);
  // The battery: charge drawn, open-circuit voltage falling linearly with it, sag under load.
  const BatteryModel& b = cfg_.battery;
  amps_ = amps;
  used_ah_ += amps * dt / 3600.0;
  const double ocv = full_volts_ - (full_volts_ - b.empty_volts) * used_ah_ * 1000.0 / b.capacity_mah;
  volts_ = std::max(0.0, ocv - amps * b.resistance);
  notify_state_changes();
}

void Robot::notify_state_changes() {
  for (auto& [port, d] : devices_) {
    if (!d.motor) continue;
    std::string now = d.motor->state();
    if (now == d.last_state) continue;
    d.last_state = std::move(now);
    tree_.notify(d.state);
  }
}

void Robot::sense(SimTime now, const Perception& base) {
  Perception p = base;
  p.pressed = bumper_;
  p.heading_deg = heading_total_;
  p.turn_rate_dps = rad2deg(w_);
  for (auto& [port, d] : devices_)
    if (d.sensor) d.sensor->step(now, p);
}

}  // namespace ev3sim
