/// @file leds.hpp
/// @brief The brick's status LEDs through ev3dev's sysfs LED class: ROOT/class/leds/NAME/{trigger,
///        brightness,max_brightness,delay_on,delay_off}. Solid patterns: trigger `none` and a
///        brightness; blinking ones: trigger `timer` with delay_on / delay_off of 500 ms.
///        When the directory does not exist (a PC), the pattern is only logged (once, at verbose).
#pragma once

#include <string>
#include <vector>

#include <ev3proto/core.hpp>

#include "ev3io/log.hpp"

namespace ev3agent {

/// Red and green brightness (0..1) of a pattern, and whether it blinks.
struct LedColour {
  double red = 0, green = 0;
  bool blink = false;
};

/// The colour of each core LED pattern (brief sec. 2: yellow / green blinking, green, orange, red
/// blinking; dark when OFF). Orange is red full and green half, as ev3dev's own ORANGE.
LedColour colour_of(ev3proto::Led l) noexcept;

/// The names ev3dev gives the four brick-status LEDs: left red, left green, right red, right green.
/// ev3dev-stretch (4.14 kernels) first, then ev3dev-jessie's names.
extern const char* const kLedNamesStretch[4];
extern const char* const kLedNamesJessie[4];

/// Writes LED patterns to sysfs.
class Leds {
 public:
  Leds(std::string sysfs_root, ev3io::Logger& log);
  /// Shows pattern @p l (every LED file written; errors logged once at verbose).
  void set(ev3proto::Led l);
  /// The LED directory in use ("" when none was found).
  const std::string& dir() const noexcept { return dir_; }

 private:
  bool write(const std::string& path, const std::string& value);
  std::string dir_;
  std::vector<std::string> names_;
  ev3io::Logger& log_;
  bool warned_ = false;
};

}  // namespace ev3agent
