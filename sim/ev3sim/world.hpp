/// @file world.hpp
/// @brief The static world the robots drive in, and its text format (docs/devices.md, "World
///        files"): bounds, walls (segments), boxes (rectangles), coloured floor patches, start
///        poses. Units are centimetres and degrees.
///
/// A world file is read line by line; each line is a statement or a comment:
///
///     # a 3 m x 2 m pen with a box and a red finish line
///     units cm
///     bounds 0 0 300 200
///     ground none reflect 30
///     wall 100 0 100 120
///     box 200 80 30 20
///     floor red rect 260 0 40 200
///     floor blue poly 20 150 60 150 40 190 reflect 12
///     start 30 30 90
///
/// parse_world() reports the first error as "FILE line L col C: what is wrong".
#pragma once

#include <string>
#include <vector>

#include "ev3sim/geometry.hpp"

namespace ev3sim {

/// The colours of the EV3 colour sensor's COL-COLOR mode, with the driver's codes 0..7.
enum class Colour : int { None = 0, Black, Blue, Green, Yellow, Red, White, Brown };
/// "none", "black", ... (the driver's names, lower case).
const char* colour_name(Colour c);
/// The colour called @p name; false when there is none.
bool colour_by_name(const std::string& name, Colour& out);
/// Reflected light (COL-REFLECT, percent) of a patch of this colour unless the file says otherwise.
int default_reflect(Colour c);
/// An RGB triple (0..255) used to draw the colour.
const char* colour_rgb(Colour c);

/// A floor patch: a polygon (a rectangle is a 4-gon) with a colour and a reflectance.
struct FloorPatch {
  Colour colour = Colour::None;
  int reflect = 0;           ///< COL-REFLECT percent
  std::vector<Vec2> poly;    ///< vertices (a simple polygon, any winding)
  int line = 0;              ///< where it was defined
};

struct Wall {
  Segment seg;
  int line = 0;
};

struct Box {
  Convex shape;  ///< a rectangle, counter-clockwise
  int line = 0;
};

struct StartPose {
  double x = 0, y = 0, heading_deg = 0;
  int line = 0;
};

struct World {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;  ///< bounds (the robots cannot leave them)
  Colour ground = Colour::None;           ///< the floor outside every patch
  int ground_reflect = 30;
  std::vector<Wall> walls;                ///< walls of the file (the bounds are walls too)
  std::vector<Box> boxes;
  std::vector<FloorPatch> patches;        ///< later patches lie on top of earlier ones
  std::vector<StartPose> starts;          ///< default poses of robots 1, 2, ...
  std::string name;                       ///< the file name, for messages

  /// Every obstacle edge: the file's walls and the four sides of the bounds.
  std::vector<Segment> all_walls() const;
  /// The floor under @p p: the topmost patch containing it, or the ground.
  void floor_at(Vec2 p, Colour& colour, int& reflect) const;
};

/// Parses the text of a world file. @p name is used in messages. Returns "" and fills @p out, or
/// the first error ("NAME line L col C: ...").
std::string parse_world(const std::string& text, const std::string& name, World& out);

/// @p w as JSON, in centimetres and degrees (`ev3-sim world FILE` prints it; the web view draws
/// it): {"name", "bounds": [x0, y0, x1, y1], "ground": {"colour", "reflect"}, "walls": [[xa, ya, xb,
/// yb], ...], "boxes": [[[x, y], ...], ...], "patches": [{"colour", "reflect", "poly": [[x, y],
/// ...]}, ...] (bottom first), "starts": [[x, y, heading], ...]}.
std::string world_json(const World& w);

}  // namespace ev3sim
