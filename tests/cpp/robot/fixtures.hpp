// Device descriptions as the device layer reports them, for the robot tests (no exceptions, no
// heap: the -fno-exceptions program uses them too).
#pragma once

#include <string_view>

#include "ev3proto/robot/device.hpp"

namespace ev3test {

/// An EV3 large motor on @p d, as a brick describes it.
inline ev3proto::robot::DeviceInfo large_motor(ev3proto::robot::Dev d) {
  using namespace ev3proto::robot;
  DeviceInfo i;
  i.dev = d;
  i.cls = DeviceClass::tacho_motor;
  i.driver = Driver::ev3_large_motor;
  i.driver_name = Text<24>("lego-ev3-l-motor");
  const MotorTexts t{"lego-ev3-l-motor", "1050", "360",
                     "run-forever run-to-abs-pos run-to-rel-pos run-timed run-direct stop reset", "coast brake hold"};
  ev3proto::robot::ReasonText why;
  parse_motor_info(t, i.motor, why);
  return i;
}

/// A sensor of driver @p driver on @p d listing @p modes, in @p mode with @p decimals, one value.
inline ev3proto::robot::DeviceInfo sensor(ev3proto::robot::Dev d, std::string_view driver, std::string_view modes,
                                          std::string_view mode, std::string_view decimals) {
  using namespace ev3proto::robot;
  DeviceInfo i;
  i.dev = d;
  i.cls = DeviceClass::lego_sensor;
  i.driver = parse_driver(driver);
  i.driver_name = Text<24>(driver);
  const SensorTexts t{driver, modes, mode, decimals, "1", ""};
  ev3proto::robot::ReasonText why;
  parse_sensor_info(t, i.sensor, why);
  return i;
}

}  // namespace ev3test
