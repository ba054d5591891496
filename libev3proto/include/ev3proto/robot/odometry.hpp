/// @file odometry.hpp
/// @brief Dead reckoning from the wheel encoders (odometry): the robot's pose (x, y, heading)
///        moved by the arc its two wheels rolled between two readings of their positions. It
///        knows where the robot started only as it is told (the operator's start pose, or 0, 0,
///        0), and drifts with every slip of a tyre: docs/devices.md "Odometry" gives the drift
///        measured against ev3-sim's truth.
#pragma once

#include <cmath>
#include <cstdint>

#include "model.hpp"

namespace ev3proto::robot {

/// A pose in the plane: millimetres, and degrees counter-clockwise from +x in [0, 360).
struct Pose {
  double x_mm = 0, y_mm = 0, heading_deg = 0;
};

/// The pose a differential-drive robot reaches from @p p when its left and right wheels roll
/// @p left_mm and @p right_mm (forward positive) on geometry @p g: along an arc whose chord is
/// taken at the middle heading.
inline Pose roll(const Pose& p, double left_mm, double right_mm, const Geometry& g) noexcept {
  const double ds = (left_mm + right_mm) / 2.0;
  const double dth = (right_mm - left_mm) / g.wheel_base_mm;  // radians, positive: left
  const double th = p.heading_deg * kPi / 180.0;
  const double mid = th + dth / 2.0;
  Pose q;
  q.x_mm = p.x_mm + ds * std::cos(mid);
  q.y_mm = p.y_mm + ds * std::sin(mid);
  double h = std::fmod((th + dth) * 180.0 / kPi, 360.0);
  q.heading_deg = h < 0 ? h + 360.0 : h;
  return q;
}

/// The robot's pose from its wheels' positions: update() with each pair read; a wheel that was
/// unplugged counts from a new zero when it is back, so rebase() then (the pose stays).
class Odometry {
 public:
  explicit Odometry(const Pose& start = {}) noexcept : pose_(start) {}

  /// Both wheels' positions (counts) read now, @p mm_per_count_left / right the arc of one count.
  void update(std::int32_t left, std::int32_t right, double mm_per_count_left, double mm_per_count_right,
              const Geometry& g) noexcept {
    if (based_)
      pose_ = roll(pose_, static_cast<double>(std::int64_t{left} - left_) * mm_per_count_left,
                   static_cast<double>(std::int64_t{right} - right_) * mm_per_count_right, g);
    left_ = left;
    right_ = right;
    based_ = true;
  }
  /// The next update() starts counting from the positions it is given.
  void rebase() noexcept { based_ = false; }
  const Pose& pose() const noexcept { return pose_; }

  /// True when the pose moved at least 1 mm or 0.5 degree from the last one reported, which it
  /// then becomes.
  bool report_due() noexcept {
    const double dh = std::fabs(pose_.heading_deg - reported_.heading_deg);
    const bool moved = std::hypot(pose_.x_mm - reported_.x_mm, pose_.y_mm - reported_.y_mm) >= 1.0 ||
                       (dh < 180.0 ? dh : 360.0 - dh) >= 0.5 || !reported_once_;
    if (moved) {
      reported_ = pose_;
      reported_once_ = true;
    }
    return moved;
  }

 private:
  Pose pose_;
  Pose reported_;
  bool reported_once_ = false;
  bool based_ = false;
  std::int32_t left_ = 0, right_ = 0;
};

}  // namespace ev3proto::robot
