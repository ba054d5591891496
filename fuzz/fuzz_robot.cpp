// libFuzzer target: the robot runtime of model A (ev3proto/robot_runtime.hpp) as the device layer
// feeds it, with every text a device file could hold taken from the input: devices appearing with a
// self-description (driver_name, max_speed, count_per_rot, commands, stop_actions; modes, mode,
// decimals, num_values, units) parsed by robot/device.hpp's parsers (garbage: device_faulty with the
// reason), readings of any attribute with any text (numbers near the edges, garbage, raw bytes),
// failed reads and writes, unplugs, the battery, the LEDs, time passing and the agent core's
// controls of a behaviour (explore, drive, wait, a custom definition from the input). After every
// step: a refused self-description names its file; a tick leaves no deadline in the past; every
// write goes to a device of the model, to an attribute of its class, with a value that fits; once
// the battery shut the robot down no motor is told to run; no queue overflowed.
// Also linked with replay_main.cpp to run the committed corpus under gcc and armel.
#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "ev3proto/robot_runtime.hpp"
#include "fuzz_input.hpp"

namespace {

using namespace ev3proto;
using namespace ev3proto::robot;

/// A text a device file might hold: a word of the model's vocabulary, a number near an edge, or
/// raw bytes.
std::string text(fuzzin::Reader& in) {
  static constexpr const char* kTexts[] = {
      "0", "1", "-1", "360", "1050", "1560", "183", "2550", "2147483647", "-2147483648", "2147483648",
      "99999999999", "7500000", "6000000", "", " ", "\n", "1\n", "12a", "+5", "0x10", "1.5",
      "lego-ev3-l-motor", "lego-ev3-m-motor", "lego-ev3-us", "lego-ev3-touch", "lego-ev3-color",
      "lego-ev3-gyro", "run-forever run-to-abs-pos run-to-rel-pos run-timed run-direct stop reset",
      "coast brake hold", "coast", "US-DIST-CM US-DIST-IN US-LISTEN US-SI-CM US-SI-IN",
      "US-DIST-CM", "TOUCH", "COL-REFLECT COL-AMBIENT COL-COLOR REF-RAW RGB-RAW COL-CAL", "COL-COLOR",
      "GYRO-ANG", "cm", "pct", "running", "running ramping", "holding", "stalled", "overloaded",
      "running stalled", "bogus", "10", "3", "8", "9"};
  constexpr std::size_t kN = sizeof kTexts / sizeof kTexts[0];
  const std::uint8_t b = in.byte();
  if (b < 200) return kTexts[b % kN];
  return in.bytes(24);
}

constexpr Dev kPorts[] = {Dev::outA, Dev::outB, Dev::outC, Dev::outD, Dev::in1, Dev::in2, Dev::in3, Dev::in4};

/// A write the runtime may make: to a port of the model (or an LED), to an attribute of that
/// device's class, with a value of at most what Write holds.
void check_write(const Write& w, bool off) {
  if (is_out_port(w.dev)) {
    const Attr ok[] = {Attr::command, Attr::position_sp, Attr::speed_sp, Attr::time_sp, Attr::stop_action,
                       Attr::polarity, Attr::position};
    bool found = false;
    for (Attr a : ok) found = found || a == w.attr;
    if (!found) fuzzin::violation("a motor write to an attribute motors do not take");
    if (off && w.attr == Attr::command && w.value.view().rfind("run", 0) == 0)
      fuzzin::violation("a motor told to run after the battery shut the robot down");
  } else if (is_in_port(w.dev)) {
    if (w.attr != Attr::mode && w.attr != Attr::poll_ms && w.attr != Attr::command)
      fuzzin::violation("a sensor write to an attribute sensors do not take");
  } else if (is_led(w.dev)) {
    if (w.attr != Attr::brightness && w.attr != Attr::trigger && w.attr != Attr::delay_on &&
        w.attr != Attr::delay_off)
      fuzzin::violation("an LED write to an attribute LEDs do not take");
  } else {
    fuzzin::violation("a write to the battery");
  }
}

/// A device appears on @p port: its self-description parsed (@p ok) into @p info, or refused with
/// @p why, which must then say why; the runtime is told as the device layer tells it.
void appear(Runtime& rt, Dev port, bool ok, DeviceInfo& info, DeviceClass cls, Driver driver, std::string_view name,
            const ReasonText& why, Millis now) {
  if (!ok) {
    if (why.view().empty()) fuzzin::violation("a self-description refused without a reason");
    rt.device_faulty(port, why.view(), now);
    return;
  }
  info.dev = port;
  info.cls = cls;
  info.driver = driver;
  info.driver_name = decltype(info.driver_name)(name.substr(0, 23));
  rt.device_connected(info, now);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fuzzin::Reader in{data, size};
  RuntimeConfig cfg;
  static Runtime* rt = nullptr;  // large: off the fuzzer's stack
  delete rt;
  rt = new Runtime(cfg, 0);
  Millis now = 0;
  Write last{};
  bool wrote = false;
  while (in.n > 0) {
    const bool off = rt->off();  // a motor write made as the battery shuts it down is not after it
    const std::uint8_t op = in.byte();
    const Dev port = kPorts[in.byte() % 8];
    switch (op % 12) {
      case 0: {  // a motor appears: its texts, parsed as the device layer does
        const std::string d = text(in), ms = text(in), cpr = text(in), cmds = text(in), sa = text(in);
        MotorTexts t{d, ms, cpr, cmds, sa};
        DeviceInfo info;
        ReasonText why;
        const bool ok = parse_motor_info(t, info.motor, why);
        if (ok && (info.motor.max_speed <= 0 || info.motor.count_per_rot <= 0)) fuzzin::violation("a motor limit taken as <= 0");
        appear(*rt, port, ok, info, DeviceClass::tacho_motor, info.motor.driver, d, why, now);
        break;
      }
      case 1: {  // a sensor appears
        const std::string d = text(in), modes = text(in), mode = text(in), dec = text(in), nv = text(in), u = text(in);
        SensorTexts t{d, modes, mode, dec, nv, u};
        DeviceInfo info;
        ReasonText why;
        const bool ok = parse_sensor_info(t, info.sensor, why);
        if (ok && (info.sensor.decimals > kMaxDecimals || info.sensor.num_values > kMaxValues || info.sensor.mode_count == 0))
          fuzzin::violation("a sensor's self-description taken out of its bounds");
        appear(*rt, port, ok, info, DeviceClass::lego_sensor, info.sensor.driver, d, why, now);
        break;
      }
      case 2:
      case 3: {  // a reading of any attribute of a port, or of the battery
        const Dev dev = (op & 0x80) ? Dev::battery : port;
        const Attr attr = static_cast<Attr>(in.byte() % kAttrCount);
        rt->reading(dev, attr, text(in), now);
        break;
      }
      case 4: {  // this tick's planned reads, each with a text from the input
        ReadPlan p;
        rt->plan_reads(p, now);
        if (p.count > ReadPlan::kMax) fuzzin::violation("a read plan beyond its bound");
        for (std::size_t i = 0; i < p.count; ++i) rt->reading(p.reads[i].dev, p.reads[i].attr, text(in), now);
        rt->tick(now);
        if (rt->next_deadline() < now) fuzzin::violation("a deadline left behind by a tick");
        break;
      }
      case 5: {
        static constexpr int kErr[] = {EBUSY, EINVAL, EIO, ENXIO, ETIMEDOUT, EAGAIN, EACCES, EPERM, EOPNOTSUPP, 0};
        const Attr attr = static_cast<Attr>(in.byte() % kAttrCount);
        rt->read_failed(port, attr, kErr[in.byte() % 10], now);
        break;
      }
      case 6:
        if (wrote) rt->write_failed(last, (in.byte() & 1) ? EBUSY : EIO, now);
        break;
      case 7: rt->device_disconnected(port, now); break;
      case 8:
        now += in.u16() % 3000u;
        rt->tick(now);
        if (rt->next_deadline() < now) fuzzin::violation("a deadline left behind by a tick");
        break;
      case 9: {  // the agent core's control of a behaviour
        static constexpr const char* kArgs[] = {"speed=300", "distance=20cm", "seconds=1", "angle=90", "seed=3",
                                                "speed=-50", "distance=0", "x=1"};
        const ControlKind k = static_cast<ControlKind>(in.byte() % 5);
        std::string_view args[3];
        const std::size_t n = in.byte() % 3;
        for (std::size_t i = 0; i < n; ++i) args[i] = kArgs[in.byte() % 8];
        const char* kNames[] = {"explore", "drive", "wait", "exploit", "nope"};
        rt->control(k, kNames[in.byte() % 5], args, n, now);
        break;
      }
      case 10: {  // a custom definition from the input (the first argument)
        const std::string def = in.bytes(200);
        const std::string_view args[1] = {def};
        rt->control(ControlKind::start, "custom", args, 1, now);
        break;
      }
      default:
        if (op & 0x40) {
          rt->battery_present((op & 1) != 0);
        } else {
          const Dev led = led_dev(in.byte() % kLedCount);
          rt->led_present(led, static_cast<std::int32_t>(in.byte()) - 8);
          rt->led(static_cast<Led>(in.byte() % 6));
        }
        break;
    }
    for (Write w; rt->poll_write(w);) {
      check_write(w, off);
      last = w;
      wrote = true;
    }
    ActionResult r;
    while (rt->poll_result(r)) {
    }
    Event e;
    while (rt->poll_event(e)) {
    }
    Report rep;
    while (rt->poll_report(rep)) {
    }
    if (rt->dropped() != 0) fuzzin::violation("a write or event queue overflowed");
  }
  return 0;
}
