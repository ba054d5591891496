#include "ev3sim/drivers.hpp"

namespace ev3sim {

namespace {

// max_speed = rated rpm * count_per_rot / 60 (ev3_motor_defs.c); PID gains after probe.
// accel: how fast the speed regulator brings the motor to its setpoint under the robot's load
// (a model: about 0.13 s from 0 to 1050 deg/s for the large motor).
const MotorDef kMotors[] = {
    {"lego-ev3-l-motor", 1050, 360, {1000, 60, 0}, {80000, 0, 0}, 8000.0},
    {"lego-ev3-m-motor", 1560, 360, {1000, 60, 0}, {160000, 0, 0}, 16000.0},
};

using D = DataType;
const SensorDef kSensors[] = {
    {"lego-ev3-touch", SensorKind::Touch, false, {{"TOUCH", 1, 0, "", D::U8}}},
    {"lego-ev3-color",
     SensorKind::Colour,
     true,
     {{"COL-REFLECT", 1, 0, "pct", D::S8},
      {"COL-AMBIENT", 1, 0, "pct", D::S8},
      {"COL-COLOR", 1, 0, "col", D::S8},
      {"REF-RAW", 2, 0, "", D::S16},
      {"RGB-RAW", 4, 0, "", D::S16},
      {"COL-CAL", 3, 0, "", D::U16}}},
    {"lego-ev3-us",
     SensorKind::Ultrasonic,
     true,
     {{"US-DIST-CM", 1, 1, "cm", D::S16},
      {"US-DIST-IN", 1, 1, "in", D::S16},
      {"US-LISTEN", 1, 0, "", D::S8},
      {"US-SI-CM", 1, 1, "cm", D::S16},
      {"US-SI-IN", 1, 1, "in", D::S16},
      {"US-DC-CM", 1, 1, "cm", D::S16},
      {"US-DC-IN", 1, 1, "in", D::S16}}},
    {"lego-ev3-gyro",
     SensorKind::Gyro,
     true,
     {{"GYRO-ANG", 1, 0, "deg", D::S16},
      {"GYRO-RATE", 1, 0, "d/s", D::S16},
      {"GYRO-FAS", 1, 0, "", D::S16},
      {"GYRO-G&A", 2, 0, "", D::S16},
      {"GYRO-CAL", 4, 0, "", D::S16},
      {"TILT-RATE", 1, 0, "d/s", D::S16},
      {"TILT-ANG", 1, 0, "deg", D::S16}}},
};

}  // namespace

const char* data_type_name(DataType t) {
  switch (t) {
    case DataType::U8: return "u8";
    case DataType::S8: return "s8";
    case DataType::U16: return "u16";
    case DataType::S16: return "s16";
    case DataType::S32: return "s32";
  }
  return "s32";
}

int data_type_size(DataType t) {
  switch (t) {
    case DataType::U8:
    case DataType::S8: return 1;
    case DataType::U16:
    case DataType::S16: return 2;
    case DataType::S32: return 4;
  }
  return 4;
}

const MotorDef* motor_def(const std::string& name) {
  for (const MotorDef& m : kMotors)
    if (name == m.driver_name) return &m;
  return nullptr;
}

const SensorDef* sensor_def(const std::string& name) {
  for (const SensorDef& s : kSensors)
    if (name == s.driver_name) return &s;
  return nullptr;
}

std::vector<std::string> driver_names() {
  std::vector<std::string> out;
  for (const MotorDef& m : kMotors) out.emplace_back(m.driver_name);
  for (const SensorDef& s : kSensors) out.emplace_back(s.driver_name);
  return out;
}

}  // namespace ev3sim
