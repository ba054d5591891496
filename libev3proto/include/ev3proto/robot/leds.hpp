/// @file leds.hpp
/// @brief The lifecycle made visible on the brick's two status LEDs (each a red and a green LED in
///        ev3dev's `leds` class). Outside tests read this mapping: keep it exactly.
///
/// Colours are fractions of `max_brightness` on the (red, green) LEDs of both sides: yellow
/// (0.1, 1), green (0, 1), orange (1, 0.5), red (1, 0). Blinking is the `timer` trigger with equal
/// `delay_on` and `delay_off`; solid is trigger `none` and the brightness. IDLE blinking yellow,
/// ACTIVE blinking green, WORKING solid green, PAUSED solid orange, PANIC blinking red, OFF dark.
#pragma once

#include <cstddef>
#include <cstdint>

#include "../core.hpp"
#include "command.hpp"
#include "device.hpp"

namespace ev3proto::robot {

/// One pattern: red and green as per-mille of max_brightness, and whether it blinks.
struct LedColour {
  std::uint16_t red_permille = 0;
  std::uint16_t green_permille = 0;
  bool blink = false;
};

/// delay_on = delay_off of the blinking patterns (ms).
inline constexpr std::int32_t kBlinkMs = 500;

/// The colour of each lifecycle LED pattern (core.hpp Led, AgentLogic LedOf).
constexpr LedColour colour_of(Led l) noexcept {
  switch (l) {
    case Led::YELLOW_BLINK: return {100, 1000, true};
    case Led::GREEN_BLINK: return {0, 1000, true};
    case Led::GREEN: return {0, 1000, false};
    case Led::ORANGE: return {1000, 500, false};
    case Led::RED_BLINK: return {1000, 0, true};
    case Led::DARK: return {0, 0, false};
  }
  return {};
}

/// The brightness of @p permille of @p max_brightness, rounded half up (0.1 of 255 = 26, 0.5 = 128).
constexpr std::int32_t brightness_of(std::uint16_t permille, std::int32_t max_brightness) noexcept {
  return static_cast<std::int32_t>((static_cast<std::int64_t>(permille) * max_brightness + 500) / 1000);
}

/// Appends the writes that show pattern @p l on LED @p led (led_left_red ... led_right_green) whose
/// max_brightness is @p max. Solid, or a blinking LED that stays dark: trigger none, then the
/// brightness. Blinking: trigger timer, delay_on, delay_off, then the brightness: Linux takes a
/// brightness written while the timer runs as the brightness of the on phase (written before the
/// trigger it would blink at max_brightness).
template <std::size_t N>
void led_writes(Led l, Dev led, std::int32_t max, WriteQueue<N>& w) noexcept {
  const LedColour c = colour_of(l);
  const bool red = led == Dev::led_left_red || led == Dev::led_right_red;
  const std::int32_t b = brightness_of(red ? c.red_permille : c.green_permille, max);
  if (c.blink && b > 0) {
    w.push(led, Attr::trigger, "timer");
    w.push_int(led, Attr::delay_on, kBlinkMs);
    w.push_int(led, Attr::delay_off, kBlinkMs);
  } else {
    w.push(led, Attr::trigger, "none");
  }
  w.push_int(led, Attr::brightness, b);
}

}  // namespace ev3proto::robot
