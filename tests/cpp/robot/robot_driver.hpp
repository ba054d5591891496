// Transcript driver of the robot runtime (tests/cpp/testdata/action_*.txt, robot_*.txt).
//
// It runs the loop the agent program will run (docs/devices.md "The robot runtime"): at each of the
// runtime's deadlines it takes the reads plan_reads() lists from a test double of the brick
// (world.hpp), feeds them, ticks, and makes the writes; unplugged devices are found by ENODEV on a
// read or write, or by a rescan once a second. Time is simulated (1 ms steps).
//
// Commands (one per input line):
//   model [ports=SPEC] [wheel=MM] [base=MM] [tick=MS] [watchdog=MS]   a new brick and runtime (model A defaults)
//   plug-all                      model A's five devices, the four LEDs and the battery
//   plug PORT DRIVER [max_speed=N] [count_per_rot=N] [commands=a,b] [stop_actions=a,b]
//        [garbage=max_speed] [mode=NAME]   a device appears and the device layer reports it
//   unplug PORT                   the device is gone from the brick
//   set PORT valueN=TEXT...       a sensor's value files
//   touch press|release           the bumper (in1 unless moved)
//   distance CM                   what the ultrasonic sees
//   battery VOLTS|TEXT            voltage_now (VOLTS x 10^6, or the text as is)
//   fault PORT ATTR read|write ERRNO   the next read / write of that file fails so
//   run ACTION                    Runtime::run(): drive-distance mm= speed= [stop=], turn deg= speed=
//                                 [stop=], forever speed= | left= right= [stop=], stop coast|brake|hold,
//                                 pause ms= [sensors=in3,in4], wait ms=, repeat N: ACTION; ACTION...
//   cmd PORT COMMAND [ATTR=VALUE...]  one command through its own Tacho / Sensor logic (not the
//                                 runtime's): run-forever speed_sp=, run-to-abs-pos / run-to-rel-pos
//                                 position_sp= speed_sp= stop_action=, run-timed time_sp= speed_sp=
//                                 stop_action=, stop stop_action=, reset, position=N; a sensor: mode NAME
//   raw PORT ATTR VALUE           a write straight to the device double (what a naive client does)
//   control KIND [NAME ARGS...]   a control of the agent core (start drive speed=300, pause, ...);
//                                 start custom DEFINITION [-- ARGS...]: the definition (one line, ';'
//                                 between statements) is one argument
//   led PATTERN                   the agent core's LED pattern (GREEN_BLINK ...)
//   advance MS                    run the loop MS milliseconds
//   contact                       the node heard a master now (Runtime::contact: arms the watchdog)
//   heartbeat MS                  a contact every MS ms while the loop runs (0: none, the master is lost)
//   stall MS                      the program stalls MS ms: the world goes on, the runtime is not called
//   until result|event|write [max=MS]   run until the runtime gives one (default max 20000)
//   model ... pose=MS             the pose reports (odometry) every MS ms while it works (default: none)
//   where                         wheel travel, distance and heading since the last run / start / mark
//   motor PORT                    the motor's state, position and speed as its files would say
//   block PORT / unblock PORT     the wheel is held fast (it does not turn) / free again
//   mark                          start measuring travel from here
//   reads                         the read plan of the next tick
//   leds                          the LED files written
//   modes PORT                    when the sensor's mode was written
// Output: "<ms> write PORT ATTR VALUE", "<ms> event NAME PARAMS... [bits=N]", "<ms> result OUTCOME:
// DETAIL", "<ms> report PORT MODE VALUES", "<ms> write-failed ...", "<ms> watchdog: held (last contact
// MS)" / "released" when the contact watchdog's hold changes, and the answers of the queries.
#pragma once

#include <cerrno>
#include <cmath>
#include <cstring>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "ev3proto/robot_runtime.hpp"
#include "world.hpp"

namespace ev3test {

using namespace ev3proto::robot;

class RobotDriver {
 public:
  RobotDriver() { reset(quiet(RuntimeConfig{})); }

  std::vector<std::string> run(const std::vector<std::string>& input) {
    out_.clear();
    for (const std::string& line : input) command(line);
    return out_;
  }

 private:
  /// The transcripts' runtime reports no pose unless `model pose=MS` asks for it.
  static RuntimeConfig quiet(RuntimeConfig cfg) {
    cfg.pose_ms = 0;
    return cfg;
  }

  void reset(const RuntimeConfig& cfg) {
    cfg_ = cfg;
    world_ = World{};
    now_ = 0;
    rt_ = std::make_unique<Runtime>(cfg_, now_);
    next_rescan_ = 1000;
    known_.clear();
    tachos_.clear();
    sensors_.clear();
    held_ = false;
    heartbeat_ = 0;
  }

  static std::vector<std::string> words(const std::string& s) {
    std::istringstream in(s);
    std::vector<std::string> w;
    for (std::string x; in >> x;) w.push_back(x);
    return w;
  }
  static bool kv(const std::string& w, const std::string& key, std::string& value) {
    if (w.rfind(key + "=", 0) != 0) return false;
    value = w.substr(key.size() + 1);
    return true;
  }
  void say(const std::string& s) { out_.push_back(s); }
  void at(const std::string& s) { say(std::to_string(now_) + " " + s); }

  static int errno_of(const std::string& n) {
    if (n == "EBUSY") return EBUSY;
    if (n == "EINVAL") return EINVAL;
    if (n == "EIO") return EIO;
    if (n == "ENODEV") return ENODEV;
    if (n == "ETIMEDOUT") return ETIMEDOUT;
    return EIO;
  }

  void command(const std::string& line) {
    const auto w = words(line);
    if (w.empty()) return;
    const std::string& c = w[0];
    std::string v;
    if (c == "model") {
      RuntimeConfig cfg = quiet(RuntimeConfig{});
      for (std::size_t i = 1; i < w.size(); ++i) {
        if (kv(w[i], "ports", v)) {
          ReasonText why;
          if (!parse_ports(v, cfg.ports, why)) return say("error: " + std::string(why.view()));
        } else if (kv(w[i], "wheel", v)) {
          cfg.geo.wheel_diameter_mm = std::stod(v);
        } else if (kv(w[i], "base", v)) {
          cfg.geo.wheel_base_mm = std::stod(v);
        } else if (kv(w[i], "tick", v)) {
          cfg.tick_ms = std::stoul(v);
        } else if (kv(w[i], "watchdog", v)) {
          cfg.watchdog_ms = std::stoul(v);
        } else if (kv(w[i], "pose", v)) {
          cfg.pose_ms = std::stoul(v);
        } else {
          return say("error: model takes ports=, wheel=, base=, tick=, watchdog=, pose=");
        }
      }
      reset(cfg);
      return say("ok");
    }
    if (c == "plug-all") {
      for (std::size_t i = 0; i < 4; ++i) {
        world_.leds[led_dev(i)];
        rt_->led_present(led_dev(i), 255);
      }
      rt_->battery_present(true);
      plug(cfg_.ports.of(Role::left), "lego-ev3-l-motor", {});
      plug(cfg_.ports.of(Role::right), "lego-ev3-l-motor", {});
      plug(cfg_.ports.of(Role::touch), "lego-ev3-touch", {});
      plug(cfg_.ports.of(Role::colour), "lego-ev3-color", {});
      plug(cfg_.ports.of(Role::ultrasonic), "lego-ev3-us", {});
      return;
    }
    if (c == "plug" && w.size() >= 3) {
      Dev d{};
      if (!parse_port(w[1], d)) return say("error: port " + w[1]);
      return plug(d, w[2], std::vector<std::string>(w.begin() + 3, w.end()));
    }
    if (c == "unplug" && w.size() == 2) {
      Dev d{};
      if (!parse_port(w[1], d)) return say("error: port " + w[1]);
      world_.motors.erase(d);
      world_.sensors.erase(d);
      return;
    }
    if (c == "set" && w.size() >= 3) {
      Dev d{};
      if (!parse_port(w[1], d) || world_.sensors.count(d) == 0) return say("error: no sensor on " + w[1]);
      for (std::size_t i = 2; i < w.size(); ++i) {
        const auto eq = w[i].find('=');
        if (w[i].rfind("value", 0) != 0 || eq == std::string::npos) return say("error: set takes valueN=TEXT");
        world_.sensors[d].values[std::stoul(w[i].substr(5, eq - 5))] = w[i].substr(eq + 1);
      }
      return;
    }
    if (c == "touch" && w.size() == 2) {
      const Dev d = cfg_.ports.of(Role::touch);
      if (world_.sensors.count(d) != 0) world_.sensors[d].values[0] = w[1] == "press" ? "1" : "0";
      return;
    }
    if (c == "distance" && w.size() == 2) {
      const Dev d = cfg_.ports.of(Role::ultrasonic);
      if (world_.sensors.count(d) != 0)
        world_.sensors[d].values[0] = std::to_string(std::llround(std::stod(w[1]) * 10));
      return;
    }
    if (c == "battery" && w.size() == 2) {
      char* end = nullptr;
      const double volts = std::strtod(w[1].c_str(), &end);
      world_.battery_uv = *end == '\0' ? std::to_string(std::llround(volts * 1e6)) : w[1];
      return;
    }
    if (c == "fault" && w.size() == 5) {
      Dev d{};
      Attr a{};
      if (!parse_port(w[1], d) && w[1] != "battery") return say("error: port " + w[1]);
      if (w[1] == "battery") d = Dev::battery;
      if (!parse_attr(w[2], a)) return say("error: attr " + w[2]);
      world_.faults[{d, a, w[3] == "read" ? 'r' : 'w'}] = errno_of(w[4]);
      return;
    }
    if (c == "run") {
      action::Plan p;
      std::string err;
      if (!parse_plan(line.substr(line.find("run") + 3), p, err)) return say("error: " + err);
      mark();
      rt_->run(p, now_);
      return drain();
    }
    if (c == "cmd" && w.size() >= 3) return cmd(w);
    if (c == "raw" && w.size() == 4) {
      Dev d{};
      Attr a{};
      if (!parse_port(w[1], d) || !parse_attr(w[2], a)) return say("error: raw PORT ATTR VALUE");
      const int err = world_.write(d, a, w[3], now_);
      return at("raw " + w[1] + " " + w[2] + " " + w[3] + (err == 0 ? "" : " failed " + std::string(errno_name(err))));
    }
    if (c == "control" && w.size() >= 2) {
      ev3proto::ControlKind k{};
      bool found = false;
      for (auto kind : {ev3proto::ControlKind::start, ev3proto::ControlKind::pause, ev3proto::ControlKind::resume,
                        ev3proto::ControlKind::stop, ev3proto::ControlKind::restart})
        if (ev3proto::to_string(kind) == w[1]) {
          k = kind;
          found = true;
        }
      if (!found) return say("error: control " + w[1]);
      if (k == ev3proto::ControlKind::start || k == ev3proto::ControlKind::restart) {
        behaviour_ = w.size() > 2 ? w[2] : "";
        args_.assign(w.size() > 3 ? w.begin() + 3 : w.end(), w.end());
        if (behaviour_ == "custom" && w.size() > 3) {  // the definition is one argument: up to " -- "
          const std::string rest = line.substr(line.find("custom") + 7);
          const std::size_t sep = rest.find(" -- ");
          args_.assign(1, rest.substr(0, sep));
          if (sep != std::string::npos) {
            const auto more = words(rest.substr(sep + 4));
            args_.insert(args_.end(), more.begin(), more.end());
          }
        }
        mark();
      }
      std::vector<std::string_view> a(args_.begin(), args_.end());
      rt_->control(k, behaviour_, a.data(), a.size(), now_);
      return drain();
    }
    if (c == "led" && w.size() == 2) {
      for (std::size_t i = 0; i < 6; ++i) {
        const auto l = static_cast<ev3proto::Led>(i);
        if (ev3proto::to_string(l) == w[1]) {
          rt_->led(l);
          return drain();
        }
      }
      return say("error: led " + w[1]);
    }
    if (c == "advance" && w.size() == 2) return advance(now_ + std::stoul(w[1]), nullptr);
    if (c == "contact" && w.size() == 1) {  // the node heard a master now (robot_link.hpp feeds it)
      rt_->contact(now_);
      return drain();
    }
    if (c == "heartbeat" && w.size() == 2) {  // a contact every MS ms from now on (0: none)
      heartbeat_ = std::stoul(w[1]);
      next_contact_ = now_ + heartbeat_;
      return;
    }
    if (c == "stall" && w.size() == 2) {  // the program stalls: the world goes on, the runtime does not
      const Millis to = now_ + std::stoul(w[1]);
      while (now_ < to) world_.step(++now_);
      return;
    }
    if (c == "until" && w.size() >= 2) {
      Millis max = 20000;
      if (w.size() == 3 && kv(w[2], "max", v)) max = std::stoul(v);
      const std::string what = w[1];
      const Millis start = now_;
      advance(now_ + max, &what);
      if (!hit_) say("nothing (" + what + ") in " + std::to_string(now_ - start) + " ms");
      return;
    }
    if (c == "where") return where();
    if ((c == "block" || c == "unblock") && w.size() == 2) {
      Dev d{};
      if (!parse_port(w[1], d) || world_.motors.count(d) == 0) return say("error: no motor on " + w[1]);
      world_.motors[d].blocked = c == "block";
      return;
    }
    if (c == "motor" && w.size() == 2) {
      Dev d{};
      if (!parse_port(w[1], d) || world_.motors.count(d) == 0) return say("error: no motor on " + w[1]);
      const SimMotor& m = world_.motors[d];
      return say("motor " + w[1] + ": state '" + m.state() + "' position " + m.read(Attr::position) + " speed " +
                 m.read(Attr::speed));
    }
    if (c == "mark") return mark();
    if (c == "reads") {
      ReadPlan p;
      rt_->plan_reads(p, now_);
      std::string s = "reads";
      for (std::size_t i = 0; i < p.count; ++i)
        s += " " + std::string(to_string(p.reads[i].dev)) + "/" + std::string(to_string(p.reads[i].attr));
      return say(s);
    }
    if (c == "leds") {
      for (const auto& [d, attrs] : world_.leds) {
        std::string s = std::string(to_string(d)) + ":";
        for (Attr a : {Attr::trigger, Attr::brightness, Attr::delay_on, Attr::delay_off}) {
          auto f = attrs.find(a);
          if (f != attrs.end()) s += " " + std::string(to_string(a)) + "=" + f->second;
        }
        say(s);
      }
      return;
    }
    if (c == "modes" && w.size() == 2) {
      Dev d{};
      if (!parse_port(w[1], d) || world_.sensors.count(d) == 0) return say("error: no sensor on " + w[1]);
      std::string s = "mode writes at";
      for (Millis t : world_.sensors[d].mode_writes) s += " " + std::to_string(t);
      return say(s);
    }
    say("error: unknown command: " + line);
  }

  /// `cmd`: one command through a Tacho / Sensor of the driver's own, its writes made on the world.
  void cmd(const std::vector<std::string>& w) {
    Dev d{};
    if (!parse_port(w[1], d)) return say("error: port " + w[1]);
    Writes out;
    ReasonText why;
    bool ok = false;
    if (is_out_port(d)) {
      if (world_.motors.count(d) == 0) return say("error: no motor on " + w[1]);
      const SimMotor& m = world_.motors[d];
      Tacho& t = tachos_[d];
      if (!t.present()) {
        MotorTexts tx;
        const std::string ms = std::to_string(m.max_speed), cpr = std::to_string(m.count_per_rot);
        tx.driver_name = to_string(m.driver);
        tx.max_speed = ms;
        tx.count_per_rot = cpr;
        tx.commands = m.commands;
        tx.stop_actions = m.stop_actions;
        MotorInfo info;
        if (!parse_motor_info(tx, info, why)) return say("error: " + std::string(why.view()));
        t.bind(d);
        t.attach(info);
      }
      std::int32_t speed = 0, pos = 0, time = 0;
      StopAction sa = StopAction::brake;
      std::string v;
      for (std::size_t i = 3; i < w.size(); ++i) {
        if (kv(w[i], "speed_sp", v)) speed = std::stoi(v);
        else if (kv(w[i], "position_sp", v)) pos = std::stoi(v);
        else if (kv(w[i], "time_sp", v)) time = std::stoi(v);
        else if (kv(w[i], "stop_action", v)) {
          if (!parse_stop_action(v, sa)) return say("error: stop_action " + v);
        } else return say("error: " + w[i]);
      }
      const std::string& c = w[2];
      if (c == "run-forever") ok = t.apply(RunForever{speed}, out, why);
      else if (c == "run-to-abs-pos") ok = t.apply(RunToAbsPos{pos, speed, sa}, out, why);
      else if (c == "run-to-rel-pos") ok = t.apply(RunToRelPos{pos, speed, sa}, out, why);
      else if (c == "run-timed") ok = t.apply(RunTimed{time, speed, sa}, out, why);
      else if (c == "stop") ok = t.apply(Stop{sa}, out, why);
      else if (c == "reset") ok = t.apply(Reset{}, out, why);
      else if (kv(c, "position", v)) ok = t.apply(SetPosition{std::stoi(v)}, out, why);
      else return say("error: command " + c);
    } else {
      if (world_.sensors.count(d) == 0 || w[2] != "mode" || w.size() != 4) return say("error: cmd INPORT mode NAME");
      Sensor& s = sensors_[d];
      if (!s.present()) {
        s.bind(d);
        s.attach(world_.sensors[d].info());
      }
      Millis retry = 0;
      switch (s.set_mode(w[3], now_, out, why, retry)) {
        case ModeOutcome::written: ok = true; break;
        case ModeOutcome::unchanged: return at("unchanged");
        case ModeOutcome::too_soon: return at("too soon: " + std::string(why.view()) + "; retry at " + std::to_string(retry));
        case ModeOutcome::refused: break;
      }
    }
    if (!ok) return at("refused: " + std::string(why.view()));
    Write x;
    while (out.pop(x)) {
      at("write " + std::string(to_string(x.dev)) + " " + std::string(to_string(x.attr)) + " " + std::string(x.value.view()));
      const int err = world_.write(x.dev, x.attr, std::string(x.value.view()), now_);
      if (err != 0) at("write-failed " + std::string(errno_name(err)));
    }
  }

  void plug(Dev d, const std::string& driver, const std::vector<std::string>& opts) {
    const Driver drv = parse_driver(driver);
    std::string garbage_attr, v;
    DeviceInfo info;
    info.dev = d;
    info.driver = drv;
    info.driver_name = Text<24>(driver);
    if (is_out_port(d)) {
      SimMotor m;
      m.driver = drv;
      for (const auto& o : opts) {
        if (kv(o, "max_speed", v)) m.max_speed = std::stoi(v);
        else if (kv(o, "count_per_rot", v)) m.count_per_rot = std::stoi(v);
        else if (kv(o, "commands", v)) m.commands = spaced(v);
        else if (kv(o, "stop_actions", v)) m.stop_actions = spaced(v);
        else if (kv(o, "garbage", v)) garbage_attr = v;
      }
      MotorTexts t;
      const std::string ms = garbage_attr == "max_speed" ? "fast" : std::to_string(m.max_speed);
      const std::string cpr = std::to_string(m.count_per_rot);
      t.driver_name = driver;
      t.max_speed = ms;
      t.count_per_rot = cpr;
      t.commands = m.commands;
      t.stop_actions = m.stop_actions;
      ReasonText why;
      info.cls = DeviceClass::tacho_motor;
      world_.motors[d] = m;
      known_[d] = true;
      if (!parse_motor_info(t, info.motor, why)) {
        rt_->device_faulty(d, why.view(), now_);
        return drain();
      }
    } else {
      SimSensor s = SimSensor::of(drv);
      for (const auto& o : opts)
        if (kv(o, "mode", v))
          for (std::size_t i = 0; i < s.modes.size(); ++i)
            if (s.modes[i].name == v) s.mode = i;
      world_.sensors[d] = s;
      known_[d] = true;
      info.cls = DeviceClass::lego_sensor;
      info.sensor = s.info();
    }
    rt_->device_connected(info, now_);
    drain();
  }

  static std::string spaced(std::string v) {
    for (char& ch : v)
      if (ch == ',') ch = ' ';
    return v;
  }

  bool parse_step(const std::string& text, action::Step& s, std::string& err) {
    const auto w = words(text);
    if (w.empty()) {
      err = "empty action";
      return false;
    }
    std::int32_t mm = 0, deg = 0, speed = 0, left = 0, right = 0;
    Millis ms = 0;
    std::uint8_t sensors = 0;
    StopAction stop = StopAction::brake;
    bool lr = false;
    std::string v;
    for (std::size_t i = 1; i < w.size(); ++i) {
      if (kv(w[i], "mm", v)) mm = std::stoi(v);
      else if (kv(w[i], "deg", v)) deg = std::stoi(v);
      else if (kv(w[i], "speed", v)) speed = std::stoi(v);
      else if (kv(w[i], "left", v)) { left = std::stoi(v); lr = true; }
      else if (kv(w[i], "right", v)) { right = std::stoi(v); lr = true; }
      else if (kv(w[i], "ms", v)) ms = std::stoul(v);
      else if (kv(w[i], "stop", v) && parse_stop_action(v, stop)) {}
      else if (kv(w[i], "sensors", v)) {
        std::istringstream in(spaced(v));
        for (std::string p; in >> p;) {
          Dev d{};
          if (!parse_port(p, d) || !is_in_port(d)) {
            err = "sensors: " + p;
            return false;
          }
          sensors = static_cast<std::uint8_t>(sensors | (1u << Body::in_index(d)));
        }
      } else if (w[0] == "stop" && parse_stop_action(w[i], stop)) {
      } else {
        err = "bad argument " + w[i];
        return false;
      }
    }
    if (w[0] == "drive-distance") s = action::drive_distance(mm, speed, stop);
    else if (w[0] == "turn") s = action::turn(deg, speed, stop);
    else if (w[0] == "forever") s = lr ? action::run_forever(left, right, stop) : action::run_forever(speed, speed, stop);
    else if (w[0] == "stop") s = action::stop(stop);
    else if (w[0] == "pause") s = action::pause(ms, sensors);
    else if (w[0] == "wait") s = action::wait(ms);
    else {
      err = "unknown action " + w[0];
      return false;
    }
    return true;
  }

  bool parse_plan(const std::string& text, action::Plan& p, std::string& err) {
    std::string t = text;
    while (!t.empty() && t.front() == ' ') t.erase(0, 1);
    p = action::Plan{};
    if (t.rfind("repeat ", 0) == 0) {
      const auto colon = t.find(':');
      if (colon == std::string::npos) {
        err = "repeat N: ACTION; ACTION";
        return false;
      }
      p.times = static_cast<std::uint16_t>(std::stoul(t.substr(7, colon - 7)));
      std::istringstream in(t.substr(colon + 1));
      for (std::string part; std::getline(in, part, ';');) {
        if (p.count == action::kMaxSteps) {
          err = "too many steps";
          return false;
        }
        if (!parse_step(part, p.steps[p.count], err)) return false;
        ++p.count;
      }
      return true;
    }
    p.count = 1;
    return parse_step(t, p.steps[0], err);
  }

  void mark() {
    for (std::size_t w = 0; w < 2; ++w) {
      const Dev d = w == 0 ? cfg_.ports.of(Role::left) : cfg_.ports.of(Role::right);
      mark_[w] = world_.motors.count(d) != 0 ? world_.motors[d].pos : 0;
    }
  }

  void where() {
    double travel[2] = {0, 0};
    int cpr[2] = {360, 360};
    for (std::size_t w = 0; w < 2; ++w) {
      const Dev d = w == 0 ? cfg_.ports.of(Role::left) : cfg_.ports.of(Role::right);
      if (world_.motors.count(d) == 0) continue;
      travel[w] = world_.motors[d].pos - mark_[w];
      cpr[w] = world_.motors[d].count_per_rot;
    }
    const double per_count[2] = {M_PI * cfg_.geo.wheel_diameter_mm / cpr[0], M_PI * cfg_.geo.wheel_diameter_mm / cpr[1]};
    const double l = travel[0] * per_count[0], r = travel[1] * per_count[1];
    char b[160];
    std::snprintf(b, sizeof b, "where: left %+.0f right %+.0f counts, distance %.1f mm, heading %+.1f deg", travel[0],
                  travel[1], (l + r) / 2, (r - l) / cfg_.geo.wheel_base_mm * 180 / M_PI);
    say(b);
  }

  /// Runs the loop until @p to (or, with @p stop_on, until the runtime gives that kind of output).
  void advance(Millis to, const std::string* stop_on) {
    hit_ = hit_result_ = hit_event_ = hit_write_ = false;
    while (now_ < to) {
      ++now_;
      world_.step(now_);
      if (heartbeat_ != 0 && now_ >= next_contact_) {
        next_contact_ = now_ + heartbeat_;
        rt_->contact(now_);
      }
      if (now_ >= next_rescan_) {
        next_rescan_ = now_ + 1000;
        for (auto& [d, present] : known_)
          if (present && !world_.present(d)) {
            present = false;
            rt_->device_disconnected(d, now_);
          }
        drain();
      }
      if (now_ >= rt_->next_deadline()) {
        ReadPlan p;
        rt_->plan_reads(p, now_);
        for (std::size_t i = 0; i < p.count; ++i) {
          std::string text;
          const int err = world_.read(p.reads[i].dev, p.reads[i].attr, text);
          if (err == 0) {
            rt_->reading(p.reads[i].dev, p.reads[i].attr, text + "\n", now_);
          } else if (err == ENODEV) {
            known_[p.reads[i].dev] = false;
            rt_->device_disconnected(p.reads[i].dev, now_);
          } else {
            rt_->read_failed(p.reads[i].dev, p.reads[i].attr, err, now_);
          }
        }
        rt_->tick(now_);
        drain();
      }
      if (stop_on != nullptr && hit_) {
        const std::string& k = *stop_on;
        if ((k == "result" && hit_result_) || (k == "event" && hit_event_) || (k == "write" && hit_write_)) return;
      }
    }
  }

  void drain() {
    bool more = true;
    while (more) {
      more = false;
      Write w;
      while (rt_->poll_write(w)) {
        more = true;
        at("write " + std::string(to_string(w.dev)) + " " + std::string(to_string(w.attr)) + " " +
           std::string(w.value.view()));
        hit_ = hit_write_ = true;
        const int err = world_.write(w.dev, w.attr, std::string(w.value.view()), now_);
        if (err == ENODEV) {
          known_[w.dev] = false;
          rt_->device_disconnected(w.dev, now_);
        } else if (err != 0) {
          at("write-failed " + std::string(to_string(w.dev)) + " " + std::string(to_string(w.attr)) + " " +
             std::string(errno_name(err)));
          rt_->write_failed(w, err, now_);
        }
      }
      ActionResult r;
      while (rt_->poll_result(r)) {
        more = true;
        std::string s = "result " + std::string(to_string(r.outcome));
        if (r.outcome == Outcome::interrupted) s += " " + std::string(ev3proto::to_string(r.warning));
        at(s + ": " + std::string(r.detail.view()));
        hit_ = hit_result_ = true;
      }
      Event e;
      while (rt_->poll_event(e)) {
        more = true;
        std::string_view p[4];
        const std::size_t n = e.params(p);
        std::string s = "event";
        for (std::size_t i = 0; i < n; ++i) s += " " + std::string(p[i]);
        if (e.bits != 0) s += " [bits=" + std::to_string(e.bits) + "]";
        at(s);
        hit_ = hit_event_ = true;
      }
      Report rep;
      while (rt_->poll_report(rep)) {
        more = true;
        std::string s = "report " + std::string(report_port(rep)) + " " +
                        std::string(rep.mode.view());
        for (std::size_t i = 0; i < rep.count; ++i) {
          Text<24> t;
          t.append_fixed(rep.values[i].raw, rep.values[i].decimals);
          s += " " + std::string(t.view());
        }
        at(s);
      }
    }
    if (rt_->dropped() != 0) at("DROPPED " + std::to_string(rt_->dropped()));
    if (rt_->held() != held_) {
      held_ = rt_->held();
      at(held_ ? "watchdog: held (last contact " + std::to_string(rt_->last_contact()) + ")" : "watchdog: released");
    }
  }

  bool held_ = false;  // the runtime's watchdog hold, as last printed
  Millis heartbeat_ = 0, next_contact_ = 0;  // heartbeat MS: periodic contacts
  RuntimeConfig cfg_;
  World world_;
  std::unique_ptr<Runtime> rt_;
  Millis now_ = 0, next_rescan_ = 1000;
  std::map<Dev, bool> known_;
  std::map<Dev, Tacho> tachos_;
  std::map<Dev, Sensor> sensors_;
  double mark_[2] = {0, 0};
  std::string behaviour_;
  std::vector<std::string> args_;
  std::vector<std::string> out_;
  bool hit_ = false, hit_result_ = false, hit_event_ = false, hit_write_ = false;
};

}  // namespace ev3test
