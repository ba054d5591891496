#include "ev3sim/geometry.hpp"

#include <algorithm>
#include <limits>

namespace ev3sim {

double wrap_angle(double a) {
  a = std::fmod(a, 2 * kPi);
  if (a <= -kPi) a += 2 * kPi;
  if (a > kPi) a -= 2 * kPi;
  return a;
}

Convex rect(double x0, double y0, double x1, double y1) {
  return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
}

namespace {

// Projects @p poly on @p axis.
void project(const Convex& poly, Vec2 axis, double& lo, double& hi) {
  lo = std::numeric_limits<double>::infinity();
  hi = -lo;
  for (Vec2 v : poly) {
    const double d = dot(v, axis);
    lo = std::min(lo, d);
    hi = std::max(hi, d);
  }
}

// True when some edge normal of @p edges separates the shapes.
bool separated_by_edges_of(const Convex& edges, const Convex& a, const Convex& b) {
  const std::size_t n = edges.size();
  const std::size_t count = n == 2 ? 1 : n;  // a segment has one normal
  for (std::size_t i = 0; i < count; ++i) {
    const Vec2 e = edges[(i + 1) % n] - edges[i];
    const Vec2 axis{-e.y, e.x};
    if (axis.x == 0 && axis.y == 0) continue;
    double alo, ahi, blo, bhi;
    project(a, axis, alo, ahi);
    project(b, axis, blo, bhi);
    if (ahi < blo || bhi < alo) return true;
  }
  return false;
}

}  // namespace

bool overlaps(const Convex& a, const Convex& b) {
  if (a.empty() || b.empty()) return false;
  if (separated_by_edges_of(a, a, b) || separated_by_edges_of(b, a, b)) return false;
  if (a.size() == 2 && b.size() == 2) {
    // Two segments: the two normals are not enough when they are collinear; test along the line.
    const Vec2 d = a[1] - a[0];
    double alo, ahi, blo, bhi;
    project(a, d, alo, ahi);
    project(b, d, blo, bhi);
    if (ahi < blo || bhi < alo) return false;
  }
  return true;
}

std::optional<double> ray_segment(Vec2 origin, Vec2 dir, Vec2 a, Vec2 b) {
  const Vec2 e = b - a;
  const double denom = cross(dir, e);
  if (std::fabs(denom) < 1e-12) return std::nullopt;  // parallel: a grazing ray sees nothing
  const Vec2 w = a - origin;
  const double t = cross(w, e) / denom;
  const double u = cross(w, dir) / denom;
  if (t < 0 || u < 0 || u > 1) return std::nullopt;
  return t;
}

std::optional<double> ray_convex(Vec2 origin, Vec2 dir, const Convex& poly) {
  if (poly.size() >= 3 && point_in_polygon(origin, poly)) return 0.0;
  std::optional<double> best;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const auto t = ray_segment(origin, dir, poly[i], poly[(i + 1) % poly.size()]);
    if (t && (!best || *t < *best)) best = t;
  }
  return best;
}

bool point_in_polygon(Vec2 p, const std::vector<Vec2>& poly) {
  bool inside = false;
  for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const Vec2 a = poly[i], b = poly[j];
    if ((a.y > p.y) != (b.y > p.y)) {
      const double x = a.x + (p.y - a.y) * (b.x - a.x) / (b.y - a.y);
      if (p.x < x) inside = !inside;
    }
  }
  return inside;
}

}  // namespace ev3sim
