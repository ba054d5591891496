// World files: every statement, and errors that name the line and column.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "ev3sim/sim.hpp"
#include "ev3sim/world.hpp"

namespace {

using namespace ev3sim;

std::string error_of(const std::string& text) {
  World w;
  return parse_world(text, "world.txt", w);
}

TEST(WorldFile, EveryStatement) {
  World w;
  const std::string text =
      "# a pen\n"
      "units cm\n"
      "bounds 0 0 300 200   # the pen\n"
      "ground none reflect 30\n"
      "wall 100 0 100 120\n"
      "box 200 80 30 20\n"
      "\n"
      "floor red rect 260 0 40 200\n"
      "floor blue poly 20 150 60 150 40 190 reflect 12\n"
      "start 30 30 90\n"
      "start 30.5 60 -45\n";
  ASSERT_EQ(parse_world(text, "pen.txt", w), "");
  EXPECT_EQ(w.name, "pen.txt");
  EXPECT_DOUBLE_EQ(w.x1, 300);
  EXPECT_DOUBLE_EQ(w.y1, 200);
  ASSERT_EQ(w.walls.size(), 1u);
  EXPECT_EQ(w.walls[0].line, 5);
  ASSERT_EQ(w.boxes.size(), 1u);
  EXPECT_EQ(w.boxes[0].shape.size(), 4u);
  ASSERT_EQ(w.patches.size(), 2u);
  EXPECT_EQ(w.patches[0].colour, Colour::Red);
  EXPECT_EQ(w.patches[0].reflect, 45);
  EXPECT_EQ(w.patches[1].reflect, 12);
  EXPECT_EQ(w.patches[1].poly.size(), 3u);
  ASSERT_EQ(w.starts.size(), 2u);
  EXPECT_DOUBLE_EQ(w.starts[1].x, 30.5);
  EXPECT_DOUBLE_EQ(w.starts[1].heading_deg, -45);
  EXPECT_EQ(w.all_walls().size(), 5u);  // the file's wall and the four sides of the bounds

  Colour c;
  int reflect;
  w.floor_at({280, 100}, c, reflect);
  EXPECT_EQ(c, Colour::Red);
  w.floor_at({40, 170}, c, reflect);
  EXPECT_EQ(c, Colour::Blue);
  EXPECT_EQ(reflect, 12);
  w.floor_at({150, 150}, c, reflect);
  EXPECT_EQ(c, Colour::None);
  EXPECT_EQ(reflect, 30);

  // As `ev3-sim world` prints it for the web view: the shapes as ev3-sim holds them.
  EXPECT_EQ(world_json(w),
            "{\"name\": \"pen.txt\",\n"
            " \"bounds\": [0, 0, 300, 200],\n"
            " \"ground\": {\"colour\": \"none\", \"reflect\": 30},\n"
            " \"walls\": [[100, 0, 100, 120]],\n"
            " \"boxes\": [[[200, 80], [230, 80], [230, 100], [200, 100]]],\n"
            " \"patches\": [{\"colour\": \"red\", \"reflect\": 45, \"poly\": [[260, 0], [300, 0], [300, 200], [260, 200]]},\n"
            "  {\"colour\": \"blue\", \"reflect\": 12, \"poly\": [[20, 150], [60, 150], [40, 190]]}],\n"
            " \"starts\": [[30, 30, 90], [30.5, 60, -45]]}\n");
}

TEST(WorldFile, LaterPatchesLieOnTop) {
  World w;
  ASSERT_EQ(parse_world("bounds 0 0 10 10\nfloor red rect 0 0 10 10\nfloor green rect 2 2 2 2\n", "w", w), "");
  Colour c;
  int reflect;
  w.floor_at({3, 3}, c, reflect);
  EXPECT_EQ(c, Colour::Green);
  w.floor_at({8, 8}, c, reflect);
  EXPECT_EQ(c, Colour::Red);
}

TEST(WorldFile, ErrorsNameLineAndColumn) {
  const std::string b = "bounds 0 0 100 100\n";
  EXPECT_EQ(error_of(b + "wall 0 0 10 10\nwall 0 0 1 1\nfloor blue bxo 1 2 3 4\n"),
            "world.txt line 4 col 12: unknown shape 'bxo' (rect or poly)");
  EXPECT_EQ(error_of(b + "bxo 1 2 3 4\n"),
            "world.txt line 2 col 1: unknown statement 'bxo' (units, bounds, ground, wall, box, floor, start)");
  EXPECT_EQ(error_of(b + "  box 1 2 x3 4\n"), "world.txt line 2 col 11: expected width (a number), got 'x3'");
  EXPECT_EQ(error_of(b + "box 1 2 3\n"), "world.txt line 2 col 10: missing height");
  EXPECT_EQ(error_of(b + "box 1 2 3 4 5\n"), "world.txt line 2 col 13: unexpected '5'");
  EXPECT_EQ(error_of(b + "box 1 2 0 4\n"), "world.txt line 2 col 5: a box needs a positive width and height");
  EXPECT_EQ(error_of(b + "wall 5 5 5 5\n"), "world.txt line 2 col 6: a wall needs two distinct ends");
  EXPECT_EQ(error_of(b + "floor purple rect 1 1 2 2\n"),
            "world.txt line 2 col 7: unknown colour 'purple' (none, black, blue, green, yellow, red, white, brown)");
  EXPECT_EQ(error_of(b + "floor red\n"), "world.txt line 2 col 10: missing shape (rect or poly)");
  EXPECT_EQ(error_of(b + "floor red poly 1 1 2 2\n"),
            "world.txt line 2 col 16: a poly needs at least 3 points (x y pairs)");
  EXPECT_EQ(error_of(b + "floor red poly 1 1 2 2 3\n"), "world.txt line 2 col 25: missing y");
  EXPECT_EQ(error_of(b + "floor red rect 1 1 2 2 reflect 101\n"),
            "world.txt line 2 col 24: reflect must be a whole percentage 0..100");
  EXPECT_EQ(error_of(b + "units mm\n"), "world.txt line 2 col 7: unknown unit 'mm' (only 'cm')");
  EXPECT_EQ(error_of(b + "bounds 0 0 1 1\n"), "world.txt line 2 col 1: bounds given twice (first at line 1)");
  EXPECT_EQ(error_of("bounds 0 0 -1 1\n"), "world.txt line 1 col 8: bounds need x1 > x0 and y1 > y0");
  EXPECT_EQ(error_of("wall 0 0 1 1\n"), "world.txt: no bounds statement (the world needs 'bounds X0 Y0 X1 Y1')");
  EXPECT_EQ(error_of("box 90 90 20 5\n" + b),
            "world.txt line 1 col 5: the box leaves the bounds (line 2)");
  EXPECT_EQ(error_of(b + "start 1 2\n"), "world.txt line 2 col 10: missing heading in degrees");
  EXPECT_EQ(error_of(b + "start 1 2 nan\n"), "world.txt line 2 col 11: expected heading in degrees (a number), got 'nan'");
  EXPECT_EQ(error_of(b + "start 1 2 0x10\n"), "world.txt line 2 col 11: expected heading in degrees (a number), got '0x10'");
}

TEST(WorldFile, CommentsAndBlankLinesAnywhere) {
  World w;
  EXPECT_EQ(parse_world("\n# x\n\tbounds 0 0 1 1# trailing\n\n", "w", w), "");
  EXPECT_EQ(parse_world("bounds 0 0 1 1", "w", w), "");  // no final newline
}

TEST(WorldFile, TheExampleWorldsParseAndTheirStartsAreFree) {
  for (const char* name : {"pen.txt", "arena.txt"}) {
    std::ifstream in(std::string(EV3_SIM_WORLDS) + "/" + name);
    ASSERT_TRUE(in) << name;
    std::stringstream text;
    text << in.rdbuf();
    World w;
    ASSERT_EQ(parse_world(text.str(), name, w), "") << name;
    ASSERT_GE(w.starts.size(), 2u) << name;
    Sim sim(w);
    for (std::size_t i = 0; i < w.starts.size(); ++i) {
      RobotConfig cfg;
      cfg.name = "r" + std::to_string(i);
      cfg.start.p = {w.starts[i].x, w.starts[i].y};
      cfg.start.heading = deg2rad(w.starts[i].heading_deg);
      EXPECT_EQ(sim.add_robot(cfg), "") << name << " start " << i;
    }
  }
}

}  // namespace
