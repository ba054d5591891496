/// @file devices.hpp
/// @brief The device layer of ev3-agent over ev3dev's sysfs (docs/devices.md "The device layer").
///
/// Under a root (`--sysfs-root DIR`, default /sys) it finds the devices in DIR/class/tacho-motor and
/// DIR/class/lego-sensor by their port (`address`) and `driver_name`, never by the motorN / sensorN
/// index (it changes on every plug), in both generations of names (stretch `ev3-ports:outB`, jessie
/// `outB`); the four status LEDs (stretch `led0:red:brick-status` ..., jessie
/// `ev3:left:red:ev3dev` ...) and the battery (`lego-ev3-battery`, `legoev3-battery`).
///
/// Each device's attribute files are opened once and then read with one pread / written with one
/// pwrite (SysfsDevice). ENODEV, or the device's directory vanishing, means unplugged. scan(),
/// called once a second (kScanPeriodMs), finds what was plugged or unplugged since: one readdir of
/// each class directory and one pread of each known device's `address`; only a new name costs more.
///
/// It parses nothing itself beyond what discovery needs (the port, the driver): the robot logic
/// (libev3proto robot/) gets the texts and judges them.
#pragma once

#include <array>
#include <memory>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include <ev3proto/robot/device.hpp>
#include <ev3proto/timers.hpp>

#include "ev3io/sysfs.hpp"

namespace ev3io {

/// What scan() found changed.
struct DeviceChange {
  enum class Kind {
    connected,     ///< a device on a port, described in `info`
    disconnected,  ///< the device on info.dev is gone
    faulty,        ///< a device on info.dev whose description is garbage (`why`); not used
  };
  Kind kind = Kind::connected;
  ev3proto::robot::DeviceInfo info;
  std::string why;  ///< faulty: the file and what is wrong with it
  std::string dir;  ///< the class directory (ROOT/class/tacho-motor/motor3), for the log
};

/// The LED names of each generation: left red, left green, right red, right green.
extern const char* const kLedNamesStretch[4];
extern const char* const kLedNamesJessie[4];
/// The battery's names: stretch, jessie.
extern const char* const kBatteryNames[2];

class Ev3Devices {
 public:
  /// How often scan() should run: a device plugged in is found within this time.
  static constexpr ev3proto::Millis kScanPeriodMs = 1000;

  explicit Ev3Devices(std::string sysfs_root, SysfsIo& io = system_io());

  /// Looks for changes since the last scan (the first finds everything; it also finds the LEDs and
  /// the battery, once). Devices an access found gone are not reported again.
  void scan(std::vector<DeviceChange>& changes);
  /// Finds the status LEDs only (what scan() does first, once): for a program that only shows
  /// the lifecycle on them.
  void scan_leds();

  /// Reads @p a of the device on @p d. Access::gone means it was just unplugged: tell the robot
  /// runtime (device_disconnected) now; scan() will not report it again.
  AccessResult read(ev3proto::robot::Dev d, ev3proto::robot::Attr a);
  /// Writes @p value to @p a of the device on @p d (see read() for Access::gone).
  AccessResult write(ev3proto::robot::Dev d, ev3proto::robot::Attr a, std::string_view value);

  /// max_brightness of the LED @p led, 0 when it was not found.
  int led_max(ev3proto::robot::Dev led) const noexcept;
  /// True once a scan found ev3dev's device classes (class/tacho-motor or class/lego-sensor): a
  /// brick or ev3-sim, not a PC without ev3dev.
  bool ev3dev_tree() const noexcept { return classes_found_; }
  /// True when the battery was found.
  bool has_battery() const noexcept { return slots_[ev3proto::robot::index(ev3proto::robot::Dev::battery)].dev != nullptr; }
  /// True when a device is in use on @p d.
  bool present(ev3proto::robot::Dev d) const noexcept { return slots_[ev3proto::robot::index(d)].dev != nullptr; }
  /// The directory of the device on @p d ("" when none).
  std::string dir(ev3proto::robot::Dev d) const;
  /// Which generation's LED names were found ("stretch", "jessie", "" when none).
  const char* led_names() const noexcept { return led_generation_; }
  /// Entries of the class directories that are no device on a port (an I2C sensor behind a port,
  /// an address that is not a port): seen once, listed here for the log.
  const std::vector<std::string>& ignored() const noexcept { return ignored_list_; }
  /// System calls made so far by all devices (benchmarks).
  std::size_t calls() const noexcept;

 private:
  struct Slot {
    std::unique_ptr<SysfsDevice> dev;
    ev3proto::robot::DeviceClass cls = ev3proto::robot::DeviceClass::tacho_motor;
    std::string name;  ///< motor3, sensor7, led0:red:brick-status, lego-ev3-battery
    int max_brightness = 0;
  };

  void scan_class(ev3proto::robot::DeviceClass cls, std::vector<DeviceChange>& changes);
  void find_leds();
  void find_battery();
  /// Describes the new device in @p dev (its address already read as port @p port).
  DeviceChange describe(ev3proto::robot::DeviceClass cls, ev3proto::robot::Dev port, SysfsDevice& dev);
  void drop(ev3proto::robot::Dev d);
  /// Runs @p op on the device on @p d (Access::gone when there is none; dropped when it is gone).
  template <typename Op>
  AccessResult access(ev3proto::robot::Dev d, Op op);

  std::string root_;
  SysfsIo& io_;
  std::array<Slot, ev3proto::robot::kDevCount> slots_;
  std::set<std::string> ignored_;  ///< class/NAME entries that are not used (ignored or faulty)
  std::vector<std::string> ignored_list_;
  const char* led_generation_ = "";
  bool leds_looked_ = false;
  bool classes_found_ = false;
  std::size_t closed_calls_ = 0;
};

}  // namespace ev3io
