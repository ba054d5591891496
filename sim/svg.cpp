#include "ev3sim/svg.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace ev3sim {

namespace {

constexpr double kScale = 4.0;    // px per cm
constexpr double kMargin = 20.0;  // px around the world
constexpr double kLegend = 28.0;  // px of text under it

// One distinct colour per robot for its path.
const char* const kPathColours[] = {"#1f77b4", "#d62728", "#9467bd", "#ff7f0e", "#17becf", "#8c564b"};

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", v);
  return buf;
}

std::string escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '<') out += "&lt;";
    else if (c == '>') out += "&gt;";
    else if (c == '&') out += "&amp;";
    else if (c == '"') out += "&quot;";
    else out += c;
  }
  return out;
}

class Canvas {
 public:
  Canvas(const World& w) : w_(w) {}
  double x(double cx) const { return kMargin + (cx - w_.x0) * kScale; }
  double y(double cy) const { return kMargin + (w_.y1 - cy) * kScale; }
  std::string points(const std::vector<Vec2>& pts) const {
    std::string s;
    for (Vec2 p : pts) s += num(x(p.x)) + "," + num(y(p.y)) + " ";
    if (!s.empty()) s.pop_back();
    return s;
  }

 private:
  const World& w_;
};

// The body colour from the LEDs: red and green channels of the left LED pair (what a person
// looking at the brick would call its colour), grey when both are dark.
std::string led_colour(const Robot& r, SimTime now) {
  int red = 0, green = 0;
  for (std::size_t i = 0; i < 2; ++i) {  // leds() lists the left pair first
    const Led& l = r.leds()[i];
    const int b = l.shown(now);
    if (l.name.find("red") != std::string::npos) red = std::max(red, b);
    else green = std::max(green, b);
  }
  if (red == 0 && green == 0) return "#9e9e9e";
  char buf[32];
  std::snprintf(buf, sizeof buf, "#%02x%02x00", std::clamp(red, 0, 255), std::clamp(green, 0, 255));
  return buf;
}

}  // namespace

std::string snapshot_svg(const Sim& sim) {
  const World& w = sim.world();
  const Canvas c(w);
  const double width = (w.x1 - w.x0) * kScale + 2 * kMargin;
  const double height = (w.y1 - w.y0) * kScale + 2 * kMargin + kLegend;
  std::string s;
  s += "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  s += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + num(width) + "\" height=\"" + num(height) +
       "\" viewBox=\"0 0 " + num(width) + " " + num(height) + "\" font-family=\"sans-serif\">\n";
  s += "<title>ev3-sim: " + escape(w.name) + " at t = " + num(static_cast<double>(sim.now()) / 1e6) + " s</title>\n";
  s += "<rect x=\"0\" y=\"0\" width=\"" + num(width) + "\" height=\"" + num(height) + "\" fill=\"#ffffff\"/>\n";
  // The floor and its patches.
  s += "<rect x=\"" + num(c.x(w.x0)) + "\" y=\"" + num(c.y(w.y1)) + "\" width=\"" + num((w.x1 - w.x0) * kScale) +
       "\" height=\"" + num((w.y1 - w.y0) * kScale) + "\" fill=\"" + colour_rgb(w.ground) + "\"/>\n";
  for (const FloorPatch& f : w.patches)
    s += "<polygon points=\"" + c.points(f.poly) + "\" fill=\"" + colour_rgb(f.colour) +
         "\" stroke=\"#00000033\" stroke-width=\"1\"><title>" + colour_name(f.colour) + " (line " +
         std::to_string(f.line) + ")</title></polygon>\n";
  // A 50 cm grid.
  s += "<g stroke=\"#00000018\" stroke-width=\"1\">\n";
  for (double gx = std::ceil(w.x0 / 50) * 50; gx <= w.x1; gx += 50)
    s += "<line x1=\"" + num(c.x(gx)) + "\" y1=\"" + num(c.y(w.y0)) + "\" x2=\"" + num(c.x(gx)) + "\" y2=\"" + num(c.y(w.y1)) + "\"/>\n";
  for (double gy = std::ceil(w.y0 / 50) * 50; gy <= w.y1; gy += 50)
    s += "<line x1=\"" + num(c.x(w.x0)) + "\" y1=\"" + num(c.y(gy)) + "\" x2=\"" + num(c.x(w.x1)) + "\" y2=\"" + num(c.y(gy)) + "\"/>\n";
  s += "</g>\n";
  // Obstacles.
  for (const Box& b : w.boxes)
    s += "<polygon points=\"" + c.points(b.shape) + "\" fill=\"#8d6e63\" stroke=\"#3e2723\" stroke-width=\"2\"/>\n";
  s += "<rect x=\"" + num(c.x(w.x0)) + "\" y=\"" + num(c.y(w.y1)) + "\" width=\"" + num((w.x1 - w.x0) * kScale) +
       "\" height=\"" + num((w.y1 - w.y0) * kScale) + "\" fill=\"none\" stroke=\"#212121\" stroke-width=\"4\"/>\n";
  for (const Wall& wall : w.walls)
    s += "<line x1=\"" + num(c.x(wall.seg.a.x)) + "\" y1=\"" + num(c.y(wall.seg.a.y)) + "\" x2=\"" + num(c.x(wall.seg.b.x)) +
         "\" y2=\"" + num(c.y(wall.seg.b.y)) + "\" stroke=\"#212121\" stroke-width=\"4\" stroke-linecap=\"round\"/>\n";
  // Robots: path, body, heading, ultrasonic ray, bumper.
  std::size_t i = 0;
  for (const auto& rp : sim.robots()) {
    const Robot& r = *rp;
    const char* pc = kPathColours[i++ % (sizeof kPathColours / sizeof *kPathColours)];
    std::vector<Vec2> path = r.path();
    path.push_back(r.pose().p);
    s += "<circle cx=\"" + num(c.x(path.front().x)) + "\" cy=\"" + num(c.y(path.front().y)) + "\" r=\"5\" fill=\"none\" stroke=\"" +
         pc + "\" stroke-width=\"2\"/>\n";
    s += "<polyline points=\"" + c.points(path) + "\" fill=\"none\" stroke=\"" + pc +
         "\" stroke-width=\"3\" stroke-linejoin=\"round\" stroke-linecap=\"round\"/>\n";
    const double us = sim.ultrasonic_distance(r);
    const Vec2 o = r.ultrasonic_origin();
    const Vec2 dir{std::cos(r.pose().heading), std::sin(r.pose().heading)};
    const Vec2 end = o + dir * (us < 0 ? kUltrasonicRangeCm : us);
    s += "<line x1=\"" + num(c.x(o.x)) + "\" y1=\"" + num(c.y(o.y)) + "\" x2=\"" + num(c.x(end.x)) + "\" y2=\"" + num(c.y(end.y)) +
         "\" stroke=\"" + pc + "\" stroke-width=\"1.5\" stroke-dasharray=\"6 4\" opacity=\"0.7\"/>\n";
    s += "<polygon points=\"" + c.points(r.footprint()) + "\" fill=\"" + led_colour(r, sim.now()) +
         "\" fill-opacity=\"0.85\" stroke=\"" + pc + "\" stroke-width=\"2.5\"><title>" + escape(r.name()) +
         "</title></polygon>\n";
    const ModelA& m = r.config().model;
    const Vec2 nose = r.pose().to_world({m.body_front, 0});
    s += "<line x1=\"" + num(c.x(r.pose().p.x)) + "\" y1=\"" + num(c.y(r.pose().p.y)) + "\" x2=\"" + num(c.x(nose.x)) +
         "\" y2=\"" + num(c.y(nose.y)) + "\" stroke=\"#000000\" stroke-width=\"2.5\" stroke-linecap=\"round\"/>\n";
    if (r.bumper()) {
      const Vec2 a = r.pose().to_world({m.body_front, -m.bumper_half_width});
      const Vec2 b = r.pose().to_world({m.body_front, m.bumper_half_width});
      s += "<line x1=\"" + num(c.x(a.x)) + "\" y1=\"" + num(c.y(a.y)) + "\" x2=\"" + num(c.x(b.x)) + "\" y2=\"" + num(c.y(b.y)) +
           "\" stroke=\"#ff1744\" stroke-width=\"5\" stroke-linecap=\"round\"/>\n";
    }
    s += "<text x=\"" + num(c.x(r.pose().p.x) + 36) + "\" y=\"" + num(c.y(r.pose().p.y) - 10) +
         "\" font-size=\"14\" fill=\"" + pc + "\" stroke=\"#ffffff\" stroke-width=\"3\" paint-order=\"stroke\">" +
         escape(r.name()) + "</text>\n";
  }
  // Legend.
  std::string legend = escape(w.name) + "   t = " + num(static_cast<double>(sim.now()) / 1e6) + " s";
  for (const auto& rp : sim.robots())
    legend += "   " + escape(rp->name()) + ": " + num(rp->distance_travelled()) + " cm";
  s += "<text x=\"" + num(kMargin) + "\" y=\"" + num(height - 9) + "\" font-size=\"14\" fill=\"#212121\">" + legend +
       "</text>\n";
  s += "</svg>\n";
  return s;
}

}  // namespace ev3sim
