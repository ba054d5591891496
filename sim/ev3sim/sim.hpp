/// @file sim.hpp
/// @brief The whole simulation: one world, its robots, the clock. Pure: time and commands in,
///        state out; ev3-sim (sim/main.cpp) serves each robot's tree through FUSE and calls
///        advance_to() from its event loop.
///
/// Each step (kStepUs of simulated time) runs every robot's motor controllers, moves the bodies
/// (an obstacle stops a body at contact: walls, boxes, the bounds and the other robots), presses
/// the bumpers that touch something and samples every sensor.
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "ev3sim/robot.hpp"
#include "ev3sim/world.hpp"

namespace ev3sim {

/// The physics step: 1 ms of simulated time.
inline constexpr SimTime kStepUs = 1000;
/// The ultrasonic's range: nothing farther than this is seen (US-DIST-CM then reads 2550).
inline constexpr double kUltrasonicRangeCm = 255.0;

/// What a control command asks of the program beyond the simulation itself.
enum class ControlAction { None, Snapshot, Status, Quit };

struct ControlResult {
  bool ok = true;
  std::string message;       ///< what was done, or the error
  ControlAction action = ControlAction::None;
  std::string path;          ///< the file for Snapshot / Status ("" = the default)
};

class Sim {
 public:
  explicit Sim(World world);

  /// Adds a robot; "" or why it cannot stand there (out of bounds, overlapping something).
  std::string add_robot(RobotConfig cfg);
  std::vector<std::unique_ptr<Robot>>& robots() { return robots_; }
  const std::vector<std::unique_ptr<Robot>>& robots() const { return robots_; }
  Robot* robot(std::string_view name);
  const World& world() const { return world_; }
  SimTime now() const { return now_; }

  /// Steps until the clock reaches @p t (whole steps; the clock never goes back).
  void advance_to(SimTime t);
  /// One step.
  void step();

  /// Runs one control command (docs/devices.md, "Faults and control"):
  ///   unplug [ROBOT] PORT | replug [ROBOT] PORT | plug [ROBOT] PORT DRIVER
  ///   battery [ROBOT] VOLTS | garbage [ROBOT] PORT on|off | place [ROBOT] X Y HEADING
  ///   snapshot [FILE] | status [FILE] | quit
  /// ROBOT may be left out when there is one robot.
  ControlResult control(std::string_view line);

  /// The state of every robot as JSON (poses, devices, LEDs, battery).
  std::string status_json() const;

  /// The distance the ultrasonic of @p r sees along its heading (< 0: nothing within range).
  double ultrasonic_distance(const Robot& r) const;
  /// True when @p shape overlaps a wall, a box or a robot other than @p except.
  bool blocked(const Convex& shape, const Robot* except) const;

 private:
  void sense_all();
  World world_;
  std::vector<Segment> walls_;
  std::vector<std::unique_ptr<Robot>> robots_;
  SimTime now_ = 0;
};

/// Parses "x,y,heading" (cm, cm, degrees); false when malformed.
bool parse_pose(std::string_view s, Pose& out);

}  // namespace ev3sim
