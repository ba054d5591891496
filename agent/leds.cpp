#include "leds.hpp"

#include <sys/stat.h>

#include <cmath>
#include <cstdio>
#include <cstring>

namespace ev3agent {

const char* const kLedNamesStretch[4] = {"led0:red:brick-status", "led0:green:brick-status",
                                         "led1:red:brick-status", "led1:green:brick-status"};
const char* const kLedNamesJessie[4] = {"ev3:left:red:ev3dev", "ev3:left:green:ev3dev",
                                        "ev3:right:red:ev3dev", "ev3:right:green:ev3dev"};

LedColour colour_of(ev3proto::Led l) noexcept {
  using ev3proto::Led;
  switch (l) {
    case Led::YELLOW_BLINK: return {1, 1, true};
    case Led::GREEN_BLINK: return {0, 1, true};
    case Led::GREEN: return {0, 1, false};
    case Led::ORANGE: return {1, 0.5, false};
    case Led::RED_BLINK: return {1, 0, true};
    case Led::DARK: return {0, 0, false};
  }
  return {};
}

namespace {
bool is_dir(const std::string& p) {
  struct stat st {};
  return stat(p.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}
}  // namespace

Leds::Leds(std::string sysfs_root, ev3io::Logger& log) : log_(log) {
  const std::string dir = sysfs_root + "/class/leds";
  if (!is_dir(dir)) {
    log_.log(ev3io::kVerbose, "no LED directory %s: LED patterns are only logged", dir.c_str());
    return;
  }
  for (const char* const* set : {kLedNamesStretch, kLedNamesJessie}) {
    if (is_dir(dir + "/" + set[0]) || is_dir(dir + "/" + set[1])) {
      dir_ = dir;
      for (int i = 0; i < 4; ++i) names_.emplace_back(set[i]);
      return;
    }
  }
  log_.log(ev3io::kVerbose, "no ev3dev brick-status LEDs under %s: LED patterns are only logged", dir.c_str());
}

bool Leds::write(const std::string& path, const std::string& value) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  bool ok = f != nullptr && std::fputs(value.c_str(), f) >= 0;
  if (f != nullptr && std::fclose(f) != 0) ok = false;
  if (!ok && !warned_) {
    warned_ = true;
    log_.log(ev3io::kVerbose, "cannot write %s (%s); further LED errors not logged", path.c_str(),
             std::strerror(errno));
  }
  return ok;
}

void Leds::set(ev3proto::Led l) {
  log_.log(ev3io::kDebug, "LED %s", std::string(ev3proto::to_string(l)).c_str());
  if (dir_.empty()) return;
  const LedColour c = colour_of(l);
  for (std::size_t i = 0; i < names_.size(); ++i) {
    const std::string base = dir_ + "/" + names_[i];
    if (!is_dir(base)) continue;
    int max = 255;
    if (std::FILE* f = std::fopen((base + "/max_brightness").c_str(), "r")) {
      if (std::fscanf(f, "%d", &max) != 1 || max <= 0) max = 255;
      std::fclose(f);
    }
    const double frac = (i % 2 == 0) ? c.red : c.green;
    const int value = static_cast<int>(std::lround(frac * max));
    write(base + "/trigger", "none");
    write(base + "/brightness", std::to_string(value));
    if (c.blink && value > 0) {
      write(base + "/trigger", "timer");
      write(base + "/delay_on", "500");
      write(base + "/delay_off", "500");
    }
  }
}

}  // namespace ev3agent
