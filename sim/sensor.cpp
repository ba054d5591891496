#include "ev3sim/sensor.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>

namespace ev3sim {

namespace {

std::int32_t clamp_round(double v, double lo, double hi) {
  return static_cast<std::int32_t>(std::lround(std::clamp(v, lo, hi)));
}

// Range of a raw data type (what garbage draws from).
void type_range(DataType t, std::int64_t& lo, std::int64_t& hi) {
  switch (t) {
    case DataType::U8: lo = 0, hi = 255; return;
    case DataType::S8: lo = -128, hi = 127; return;
    case DataType::U16: lo = 0, hi = 65535; return;
    case DataType::S16: lo = -32768, hi = 32767; return;
    case DataType::S32: lo = -2147483648LL, hi = 2147483647LL; return;
  }
}

}  // namespace

Sensor::Sensor(const SensorDef& def, Generation gen, std::uint64_t seed)
    : def_(&def), gen_(gen), rng_(seed ^ 0x9e3779b97f4a7c15ULL) {}

std::uint64_t Sensor::next_random() {
  // splitmix64
  std::uint64_t z = (rng_ += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

int Sensor::mode_index(std::string_view name) const {
  for (std::size_t i = 0; i < def_->modes.size(); ++i)
    if (sysfs_streq(name, def_->modes[i].name)) return static_cast<int>(i);
  return -1;
}

bool Sensor::single_shot(int m) const {
  return def_->kind == SensorKind::Ultrasonic &&
         std::strncmp(def_->modes[static_cast<std::size_t>(m)].name, "US-SI-", 6) == 0;
}

Sensor::Values Sensor::measure(int m, const Perception& p) const {
  Values v{};
  const std::string name = def_->modes[static_cast<std::size_t>(m)].name;
  switch (def_->kind) {
    case SensorKind::Touch:
      v[0] = p.pressed ? 1 : 0;
      break;
    case SensorKind::Colour: {
      if (name == "COL-REFLECT") v[0] = p.reflect;
      else if (name == "COL-AMBIENT") v[0] = p.ambient;
      else if (name == "COL-COLOR") v[0] = static_cast<int>(p.colour);
      else if (name == "REF-RAW") {
        v[0] = clamp_round(p.reflect * 10.2, 0, 1020);
        v[1] = clamp_round(p.ambient * 10.2, 0, 1020);
      } else if (name == "RGB-RAW") {
        unsigned r = 0, g = 0, b = 0;
        std::sscanf(colour_rgb(p.colour), "#%02x%02x%02x", &r, &g, &b);
        const double k = 4.0 * p.reflect / 100.0;
        v[0] = clamp_round(r * k, 0, 1020);
        v[1] = clamp_round(g * k, 0, 1020);
        v[2] = clamp_round(b * k, 0, 1020);
      }
      break;  // COL-CAL: zeros
    }
    case SensorKind::Ultrasonic: {
      const bool none = p.distance_cm < 0 || p.distance_cm > 255.0;
      if (name == "US-LISTEN") v[0] = p.heard ? 1 : 0;
      else if (name.size() > 3 && name.compare(name.size() - 3, 3, "-CM") == 0)
        v[0] = none ? 2550 : clamp_round(p.distance_cm * 10.0, 0, 2550);
      else
        v[0] = none ? 1003 : clamp_round(p.distance_cm / 2.54 * 10.0, 0, 1003);
      break;
    }
    case SensorKind::Gyro: {
      // Clockwise is positive on the sensor (robot heading is counter-clockwise).
      const std::int32_t angle = clamp_round(-(p.heading_deg - gyro_zero_deg_), -32768, 32767);
      const std::int32_t rate = clamp_round(-p.turn_rate_dps, -440, 440);
      if (name == "GYRO-ANG") v[0] = angle;
      else if (name == "GYRO-RATE" || name == "GYRO-FAS") v[0] = rate;
      else if (name == "GYRO-G&A") v[0] = angle, v[1] = rate;
      break;  // GYRO-CAL, TILT-*: zeros (the robot does not tilt)
    }
  }
  return v;
}

void Sensor::step(SimTime now, const Perception& p) {
  if (gyro_zero_pending_) {
    gyro_zero_deg_ = p.heading_deg;
    gyro_zero_pending_ = false;
  }
  if (pending_mode_ >= 0 && now >= pending_done_) {
    if (!pending_fails_) {
      const int old = mode_;
      mode_ = pending_mode_;
      stale_until_ = now + kModeStaleMs * 1000;
      shot_taken_ = false;
      const std::string name = mode().name;
      if (def_->kind == SensorKind::Gyro && old != mode_ && (name == "GYRO-ANG" || name == "GYRO-G&A"))
        gyro_zero_deg_ = p.heading_deg;
    }
    pending_mode_ = -1;
  }
  if (locked(now)) return;  // frozen
  if (now < stale_until_) {
    shown_ = last_[static_cast<std::size_t>(mode_)];
  } else if (!(single_shot(mode_) && shot_taken_)) {
    shown_ = measure(mode_, p);
    last_[static_cast<std::size_t>(mode_)] = shown_;
    shot_taken_ = true;
  }
  if (garbage_) {
    std::int64_t lo = 0, hi = 0;
    type_range(mode().type, lo, hi);
    for (int i = 0; i < mode().num_values; ++i)
      shown_[static_cast<std::size_t>(i)] = static_cast<std::int32_t>(
          lo + static_cast<std::int64_t>(next_random() % static_cast<std::uint64_t>(hi - lo + 1)));
  }
}

ReadResult Sensor::read(std::string_view name) const {
  const ModeDef& m = mode();
  if (name == "mode") return {0, std::string(m.name) + "\n"};
  if (name == "modes") {
    std::string s;
    for (const ModeDef& d : def_->modes) s += std::string(s.empty() ? "" : " ") + d.name;
    return {0, s + "\n"};
  }
  if (name == "num_values") return {0, std::to_string(m.num_values) + "\n"};
  if (name == "decimals") return {0, std::to_string(m.decimals) + "\n"};
  if (name == "units") return {0, std::string(m.units) + "\n"};
  if (name == "bin_data_format") return {0, std::string(data_type_name(m.type)) + "\n"};
  if (name.size() == 6 && name.substr(0, 5) == "value" && name[5] >= '0' && name[5] <= '7') {
    const int n = name[5] - '0';
    if (n >= m.num_values) return {ENXIO, {}};
    return {0, std::to_string(shown_[static_cast<std::size_t>(n)]) + "\n"};
  }
  if (name == "bin_data") {
    std::string raw(32, '\0');
    const int size = data_type_size(m.type);
    for (int i = 0; i < m.num_values && (i + 1) * size <= 32; ++i) {
      const auto v = static_cast<std::uint32_t>(shown_[static_cast<std::size_t>(i)]);
      for (int b = 0; b < size; ++b)  // little-endian, as the EV3's ARM stores it
        raw[static_cast<std::size_t>(i * size + b)] = static_cast<char>((v >> (8 * b)) & 0xff);
    }
    return {0, raw};
  }
  if (name == "commands") {
    if (gen_ == Generation::Jessie) return {EOPNOTSUPP, {}};
    return {0, "\n"};
  }
  if (name == "fw_version") return {0, "\n"};
  if (name == "poll_ms" || name == "direct" || name == "text_value") return {EOPNOTSUPP, {}};
  return {EACCES, {}};
}

WriteResult Sensor::write(std::string_view name, std::string_view data, SimTime now) {
  if (name == "mode") {
    const int m = mode_index(data);
    if (m < 0) return {EINVAL, 0};
    if (!def_->uart) {
      mode_ = m;
      return {};
    }
    if (pending_mode_ >= 0) return {EBUSY, 0};
    const bool lockup = locked(now) || (single_shot(m) && now - last_mode_write_ < kUsSingleShotGapMs * 1000);
    last_mode_write_ = now;
    pending_mode_ = m;
    pending_fails_ = lockup;
    if (lockup) {
      if (!locked(now)) locked_until_ = now + kUsLockupMs * 1000;
      pending_done_ = now + kModeTimeoutMs * 1000;
      return {ETIMEDOUT, pending_done_};
    }
    pending_done_ = now + kModeAckMs * 1000;
    return {0, pending_done_};
  }
  if (name == "command") return {gen_ == Generation::Jessie ? EOPNOTSUPP : EINVAL, 0};
  if (name == "poll_ms" || name == "direct") return {EOPNOTSUPP, 0};
  return {EACCES, 0};
}

}  // namespace ev3sim
