#include "ev3sim/world.hpp"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include <ev3proto/json.hpp>

namespace ev3sim {

namespace {

struct ColourInfo {
  const char* name;
  int reflect;
  const char* rgb;
};
// Reflectances are plausible COL-REFLECT readings of LEGO-coloured paper/tape under the sensor's
// red LED (white paper reads near 90, black tape near 5); they are modelling choices, not data.
constexpr ColourInfo kColours[] = {
    {"none", 30, "#d9d4c7"},  {"black", 5, "#202020"},   {"blue", 10, "#2a5fd0"},
    {"green", 12, "#2e9e45"}, {"yellow", 60, "#f2d21b"}, {"red", 45, "#d63a2a"},
    {"white", 90, "#fafafa"}, {"brown", 15, "#7a4a23"},
};

struct Token {
  std::string text;
  int col = 0;  // 1-based
};

std::vector<Token> tokenize(const std::string& line) {
  std::vector<Token> out;
  std::size_t i = 0;
  while (i < line.size()) {
    const char c = line[i];
    if (c == '#') break;
    if (c == ' ' || c == '\t' || c == '\r') {
      ++i;
      continue;
    }
    Token t;
    t.col = static_cast<int>(i) + 1;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r' &&
           line[i] != '#')
      t.text += line[i++];
    out.push_back(std::move(t));
  }
  return out;
}

class LineParser {
 public:
  LineParser(const std::string& file, int line, std::vector<Token> toks, int end_col)
      : file_(file), line_(line), toks_(std::move(toks)), end_col_(end_col) {}

  std::string error_at(int col, const std::string& what) const {
    return file_ + " line " + std::to_string(line_) + " col " + std::to_string(col) + ": " + what;
  }
  /// Column of the next token (or just past the end of the line).
  int col() const { return pos_ < toks_.size() ? toks_[pos_].col : end_col_; }
  bool done() const { return pos_ >= toks_.size(); }
  const Token& peek() const { return toks_[pos_]; }
  const Token& take() { return toks_[pos_++]; }

  /// Reads a number named @p what into @p out.
  std::string number(const char* what, double& out) {
    if (done()) return error_at(col(), std::string("missing ") + what);
    const Token& t = take();
    const char* s = t.text.c_str();
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(s, &end);
    if (end == s || *end != '\0' || errno != 0 || !std::isfinite(v) ||
        t.text.find_first_of("xXpPnN") != std::string::npos)
      return error_at(t.col, std::string("expected ") + what + " (a number), got '" + t.text + "'");
    out = v;
    return {};
  }
  /// Reads a colour name.
  std::string colour(Colour& out) {
    if (done()) return error_at(col(), "missing colour name");
    const Token& t = take();
    if (!colour_by_name(t.text, out))
      return error_at(t.col, "unknown colour '" + t.text +
                                 "' (none, black, blue, green, yellow, red, white, brown)");
    return {};
  }
  /// An optional trailing `reflect PCT`.
  std::string optional_reflect(int& reflect) {
    if (done() || peek().text != "reflect") return {};
    const int kw = take().col;
    double v = 0;
    if (auto e = number("a reflectance in percent", v); !e.empty()) return e;
    if (v < 0 || v > 100 || v != std::floor(v))
      return error_at(kw, "reflect must be a whole percentage 0..100");
    reflect = static_cast<int>(v);
    return {};
  }
  std::string end() const {
    if (!done()) return error_at(toks_[pos_].col, "unexpected '" + toks_[pos_].text + "'");
    return {};
  }

 private:
  const std::string& file_;
  int line_;
  std::vector<Token> toks_;
  std::size_t pos_ = 0;
  int end_col_;
};

bool inside_bounds(const World& w, Vec2 p) {
  return p.x >= w.x0 && p.x <= w.x1 && p.y >= w.y0 && p.y <= w.y1;
}

}  // namespace

const char* colour_name(Colour c) { return kColours[static_cast<int>(c)].name; }
int default_reflect(Colour c) { return kColours[static_cast<int>(c)].reflect; }
const char* colour_rgb(Colour c) { return kColours[static_cast<int>(c)].rgb; }
bool colour_by_name(const std::string& name, Colour& out) {
  for (int i = 0; i < 8; ++i)
    if (name == kColours[i].name) {
      out = static_cast<Colour>(i);
      return true;
    }
  return false;
}

std::vector<Segment> World::all_walls() const {
  std::vector<Segment> out;
  out.reserve(walls.size() + 4);
  for (const Wall& w : walls) out.push_back(w.seg);
  out.push_back({{x0, y0}, {x1, y0}});
  out.push_back({{x1, y0}, {x1, y1}});
  out.push_back({{x1, y1}, {x0, y1}});
  out.push_back({{x0, y1}, {x0, y0}});
  return out;
}

void World::floor_at(Vec2 p, Colour& colour, int& reflect) const {
  for (auto it = patches.rbegin(); it != patches.rend(); ++it)
    if (point_in_polygon(p, it->poly)) {
      colour = it->colour;
      reflect = it->reflect;
      return;
    }
  colour = ground;
  reflect = ground_reflect;
}

std::string parse_world(const std::string& text, const std::string& name, World& out) {
  World w;
  w.name = name;
  int bounds_line = 0;
  // Objects are checked against the bounds once the whole file is read (bounds may come last).
  struct Placed {
    std::vector<Vec2> pts;
    int line, col;
    const char* what;
  };
  std::vector<Placed> placed;

  std::size_t start = 0;
  int line_no = 0;
  while (start <= text.size()) {
    std::size_t nl = text.find('\n', start);
    if (nl == std::string::npos) nl = text.size();
    const std::string line = text.substr(start, nl - start);
    start = nl + 1;
    ++line_no;
    auto toks = tokenize(line);
    if (toks.empty()) {
      if (nl == text.size()) break;
      continue;
    }
    LineParser p(name, line_no, std::move(toks), static_cast<int>(line.size()) + 1);
    const Token kw = p.take();
    std::string e;
    if (kw.text == "units") {
      if (p.done()) return p.error_at(p.col(), "missing unit (only 'cm' is supported)");
      const Token u = p.take();
      if (u.text != "cm") return p.error_at(u.col, "unknown unit '" + u.text + "' (only 'cm')");
    } else if (kw.text == "bounds") {
      if (bounds_line)
        return p.error_at(kw.col, "bounds given twice (first at line " +
                                      std::to_string(bounds_line) + ")");
      const int c = p.col();
      if (!(e = p.number("x0", w.x0)).empty() || !(e = p.number("y0", w.y0)).empty() ||
          !(e = p.number("x1", w.x1)).empty() || !(e = p.number("y1", w.y1)).empty())
        return e;
      if (w.x1 <= w.x0 || w.y1 <= w.y0)
        return p.error_at(c, "bounds need x1 > x0 and y1 > y0");
      bounds_line = line_no;
    } else if (kw.text == "ground") {
      if (!(e = p.colour(w.ground)).empty()) return e;
      w.ground_reflect = default_reflect(w.ground);
      if (!(e = p.optional_reflect(w.ground_reflect)).empty()) return e;
    } else if (kw.text == "wall") {
      Wall wall;
      wall.line = line_no;
      const int c = p.col();
      if (!(e = p.number("x1", wall.seg.a.x)).empty() || !(e = p.number("y1", wall.seg.a.y)).empty() ||
          !(e = p.number("x2", wall.seg.b.x)).empty() || !(e = p.number("y2", wall.seg.b.y)).empty())
        return e;
      if (length(wall.seg.b - wall.seg.a) < 1e-9) return p.error_at(c, "a wall needs two distinct ends");
      placed.push_back({{wall.seg.a, wall.seg.b}, line_no, c, "wall"});
      w.walls.push_back(wall);
    } else if (kw.text == "box") {
      double x, y, bw, bh;
      const int c = p.col();
      if (!(e = p.number("x", x)).empty() || !(e = p.number("y", y)).empty() ||
          !(e = p.number("width", bw)).empty() || !(e = p.number("height", bh)).empty())
        return e;
      if (bw <= 0 || bh <= 0) return p.error_at(c, "a box needs a positive width and height");
      Box b{rect(x, y, x + bw, y + bh), line_no};
      placed.push_back({b.shape, line_no, c, "box"});
      w.boxes.push_back(std::move(b));
    } else if (kw.text == "floor") {
      FloorPatch f;
      f.line = line_no;
      if (!(e = p.colour(f.colour)).empty()) return e;
      f.reflect = default_reflect(f.colour);
      if (p.done()) return p.error_at(p.col(), "missing shape (rect or poly)");
      const Token shape = p.take();
      const int c = p.col();
      if (shape.text == "rect") {
        double x, y, fw, fh;
        if (!(e = p.number("x", x)).empty() || !(e = p.number("y", y)).empty() ||
            !(e = p.number("width", fw)).empty() || !(e = p.number("height", fh)).empty())
          return e;
        if (fw <= 0 || fh <= 0) return p.error_at(c, "a rect needs a positive width and height");
        f.poly = rect(x, y, x + fw, y + fh);
      } else if (shape.text == "poly") {
        while (!p.done() && p.peek().text != "reflect") {
          Vec2 v;
          if (!(e = p.number("x", v.x)).empty() || !(e = p.number("y", v.y)).empty()) return e;
          f.poly.push_back(v);
        }
        if (f.poly.size() < 3) return p.error_at(c, "a poly needs at least 3 points (x y pairs)");
      } else {
        return p.error_at(shape.col, "unknown shape '" + shape.text + "' (rect or poly)");
      }
      if (!(e = p.optional_reflect(f.reflect)).empty()) return e;
      placed.push_back({f.poly, line_no, c, "floor patch"});
      w.patches.push_back(std::move(f));
    } else if (kw.text == "start") {
      StartPose s;
      s.line = line_no;
      const int c = p.col();
      if (!(e = p.number("x", s.x)).empty() || !(e = p.number("y", s.y)).empty() ||
          !(e = p.number("heading in degrees", s.heading_deg)).empty())
        return e;
      placed.push_back({{{s.x, s.y}}, line_no, c, "start pose"});
      w.starts.push_back(s);
    } else {
      return p.error_at(kw.col, "unknown statement '" + kw.text +
                                    "' (units, bounds, ground, wall, box, floor, start)");
    }
    if (!(e = p.end()).empty()) return e;
    if (nl == text.size()) break;
  }
  if (!bounds_line) return name + ": no bounds statement (the world needs 'bounds X0 Y0 X1 Y1')";
  for (const Placed& o : placed)
    for (Vec2 v : o.pts)
      if (!inside_bounds(w, v))
        return name + " line " + std::to_string(o.line) + " col " + std::to_string(o.col) +
               ": the " + o.what + " leaves the bounds (line " + std::to_string(bounds_line) + ")";
  out = std::move(w);
  return {};
}

namespace {

// A coordinate as JSON (ten significant digits: far below a millimetre).
std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

std::string point(Vec2 p) { return "[" + num(p.x) + ", " + num(p.y) + "]"; }

std::string polygon(const std::vector<Vec2>& poly) {
  std::string s = "[";
  for (std::size_t i = 0; i < poly.size(); ++i) s += (i ? ", " : "") + point(poly[i]);
  return s + "]";
}

}  // namespace

std::string world_json(const World& w) {
  std::string s = "{\"name\": " + ev3proto::json_quote(w.name) + ",\n \"bounds\": [" + num(w.x0) + ", " +
                  num(w.y0) + ", " + num(w.x1) + ", " + num(w.y1) + "],\n \"ground\": {\"colour\": " +
                  ev3proto::json_quote(colour_name(w.ground)) + ", \"reflect\": " +
                  std::to_string(w.ground_reflect) + "},\n \"walls\": [";
  for (std::size_t i = 0; i < w.walls.size(); ++i) {
    const Segment& g = w.walls[i].seg;
    s += std::string(i ? ", " : "") + "[" + num(g.a.x) + ", " + num(g.a.y) + ", " + num(g.b.x) + ", " +
         num(g.b.y) + "]";
  }
  s += "],\n \"boxes\": [";
  for (std::size_t i = 0; i < w.boxes.size(); ++i) s += (i ? ", " : "") + polygon(w.boxes[i].shape);
  s += "],\n \"patches\": [";
  for (std::size_t i = 0; i < w.patches.size(); ++i) {
    const FloorPatch& p = w.patches[i];
    s += std::string(i ? ",\n  " : "") + "{\"colour\": " + ev3proto::json_quote(colour_name(p.colour)) +
         ", \"reflect\": " + std::to_string(p.reflect) + ", \"poly\": " + polygon(p.poly) + "}";
  }
  s += "],\n \"starts\": [";
  for (std::size_t i = 0; i < w.starts.size(); ++i) {
    const StartPose& p = w.starts[i];
    s += std::string(i ? ", " : "") + "[" + num(p.x) + ", " + num(p.y) + ", " + num(p.heading_deg) + "]";
  }
  return s + "]}\n";
}

}  // namespace ev3sim
