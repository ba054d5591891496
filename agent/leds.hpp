/// @file leds.hpp
/// @brief The brick's status LEDs showing the lifecycle: the pattern of each state is the robot
///        library's (libev3proto robot/leds.hpp: yellow (0.1, 1), green (0, 1), orange (1, 0.5),
///        red (1, 0) of max_brightness on the red and green LEDs; blinking = trigger `timer`), the
///        files are written through the device layer (io/ev3io/devices.hpp: each file opened once,
///        one pwrite per write). When there are no LEDs (a PC), the pattern is only logged.
#pragma once

#include <string>

#include <ev3proto/core.hpp>

#include "ev3io/devices.hpp"
#include "ev3io/log.hpp"

namespace ev3agent {

/// Red and green brightness (0..1) of a pattern, and whether it blinks.
struct LedColour {
  double red = 0, green = 0;
  bool blink = false;
};

/// The colour of each core LED pattern (robot::colour_of as fractions).
LedColour colour_of(ev3proto::Led l) noexcept;

/// Writes LED patterns to sysfs.
class Leds {
 public:
  Leds(std::string sysfs_root, ev3io::Logger& log);
  /// Shows pattern @p l (every LED file written; errors logged once at verbose).
  void set(ev3proto::Led l);
  /// The LED directory in use ("" when none was found).
  const std::string& dir() const noexcept { return dir_; }

 private:
  ev3io::Ev3Devices devices_;
  std::string dir_;
  ev3io::Logger& log_;
  bool warned_ = false;
};

}  // namespace ev3agent
