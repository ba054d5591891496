/// @file geometry.hpp
/// @brief 2D geometry of the simulated world (centimetres): points, segments, convex polygons,
///        overlap tests (separating axes) and ray casts. Pure functions, no state.
///
/// Frame: x to the right, y up, angles counter-clockwise from +x (radians inside the library,
/// degrees in files and on the command line).
#pragma once

#include <cmath>
#include <optional>
#include <vector>

namespace ev3sim {

inline constexpr double kPi = 3.14159265358979323846;

inline double deg2rad(double d) { return d * kPi / 180.0; }
inline double rad2deg(double r) { return r * 180.0 / kPi; }
/// The angle in (-pi, pi].
double wrap_angle(double a);

struct Vec2 {
  double x = 0;
  double y = 0;
};
inline Vec2 operator+(Vec2 a, Vec2 b) { return {a.x + b.x, a.y + b.y}; }
inline Vec2 operator-(Vec2 a, Vec2 b) { return {a.x - b.x, a.y - b.y}; }
inline Vec2 operator*(Vec2 a, double k) { return {a.x * k, a.y * k}; }
inline double dot(Vec2 a, Vec2 b) { return a.x * b.x + a.y * b.y; }
inline double cross(Vec2 a, Vec2 b) { return a.x * b.y - a.y * b.x; }
inline double length(Vec2 a) { return std::sqrt(dot(a, a)); }
/// @p p rotated by @p angle (radians) about the origin.
inline Vec2 rotate(Vec2 p, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return {c * p.x - s * p.y, s * p.x + c * p.y};
}

/// A pose: position and heading (radians).
struct Pose {
  Vec2 p;
  double heading = 0;
  /// A point given in the body frame (x forward, y to the left) in world coordinates.
  Vec2 to_world(Vec2 body) const { return p + rotate(body, heading); }
};

struct Segment {
  Vec2 a;
  Vec2 b;
};

/// A convex polygon, vertices in counter-clockwise order (a segment is a 2-vertex polygon).
using Convex = std::vector<Vec2>;

/// An axis-aligned rectangle as a convex polygon.
Convex rect(double x0, double y0, double x1, double y1);

/// True when the convex shapes (polygons or segments) overlap (touching counts as overlap).
bool overlaps(const Convex& a, const Convex& b);

/// Distance along the ray from @p origin in direction @p dir (unit) to the first crossing of the
/// segment a-b, or nothing.
std::optional<double> ray_segment(Vec2 origin, Vec2 dir, Vec2 a, Vec2 b);
/// Distance along the ray to the boundary of the convex polygon @p poly (0 when the origin is
/// inside), or nothing.
std::optional<double> ray_convex(Vec2 origin, Vec2 dir, const Convex& poly);

/// True when @p p lies inside the (possibly concave) simple polygon @p poly (even-odd rule).
bool point_in_polygon(Vec2 p, const std::vector<Vec2>& poly);

}  // namespace ev3sim
