/// @file drivers.hpp
/// @brief Facts of the ev3dev drivers the simulator emulates (ev3dev/lego-linux-drivers:
///        motors/ev3_motor_defs.c, sensors/ev3_uart_sensor_defs.c, sensors/ev3_analog_sensor_defs.c,
///        ev3/legoev3_battery.c): driver names, limits, sensor modes with their value counts,
///        decimals, units and raw data formats. tests/data/ev3dev/drivers.json holds the same facts
///        for the other parts of the project; a test compares the two.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ev3sim {

/// The two generations of ev3dev names (docs/devices.md).
enum class Generation { Stretch, Jessie };

struct MotorDef {
  const char* driver_name;  ///< "lego-ev3-l-motor"
  int max_speed;            ///< counts per second (max accepted |speed_sp|)
  int count_per_rot;
  int speed_pid[3];         ///< Kp, Ki, Kd after probe
  int hold_pid[3];
  double accel;             ///< deg/s^2 the speed regulator reaches its setpoint with (model)
};

/// Raw data types of sensor values (the driver's bin_data_format).
enum class DataType { U8, S8, U16, S16, S32 };
const char* data_type_name(DataType t);
int data_type_size(DataType t);

struct ModeDef {
  const char* name;
  int num_values;
  int decimals;
  const char* units;  ///< "" when the driver gives none
  DataType type;
};

/// What kind of value source a sensor is (the simulator computes the values by kind).
enum class SensorKind { Touch, Colour, Ultrasonic, Gyro };

struct SensorDef {
  const char* driver_name;  ///< "lego-ev3-us"
  SensorKind kind;
  bool uart;                ///< EV3/UART sensor (mode changes go through the sensor: slow)
  std::vector<ModeDef> modes;
};

/// The motor driver called @p name, or nullptr.
const MotorDef* motor_def(const std::string& name);
/// The sensor driver called @p name, or nullptr.
const SensorDef* sensor_def(const std::string& name);
/// Names of every emulated driver (motors then sensors).
std::vector<std::string> driver_names();

/// Mode-change timing of EV3/UART sensors (a model; docs/devices.md, "Sensor modes"):
/// the write to `mode` returns once the sensor acknowledges (kModeAckMs), and the new mode's first
/// kModeStaleMs of data repeat what that mode last read (the stale first sample real sensors give).
inline constexpr std::int64_t kModeAckMs = 20;
inline constexpr std::int64_t kModeStaleMs = 20;
/// The ultrasonic single-shot modes lock the sensor up when the mode is written again sooner than
/// this after the previous mode write (the driver's documentation: "a delay of 250msec ... seems
/// sufficient").
inline constexpr std::int64_t kUsSingleShotGapMs = 250;
/// A locked-up sensor: the write that caused it waits 10 retries x 50 ms and fails (ETIMEDOUT);
/// the values freeze until the port resynchronises, kUsLockupMs after the lock-up.
inline constexpr std::int64_t kModeTimeoutMs = 500;
inline constexpr std::int64_t kUsLockupMs = 1500;

/// The battery driver's design voltages (AA cells), in microvolts.
inline constexpr int kBatteryMaxDesignUv = 7500000;
inline constexpr int kBatteryMinDesignUv = 6200000;

}  // namespace ev3sim
