/// @file options.hpp
/// @brief ev3-sim's command line (docs/devices.md, "Running ev3-sim"), parsed into a plain struct.
///
///     ev3-sim --world FILE --sysfs-root DIR [--robot X,Y,HEADING] [--name NAME]
///             [--sysfs-root DIR2 [--robot ...] [--name ...]]...
///             [--rate HZ] [--time-scale K] [--jessie] [--snapshot FILE.svg] [--control FIFO]
///             [--status FILE] [--duration S] [--battery-volts V] [--battery-mah N] [--seed N]
///             [--allow-other] [--log-level 0..4] [--log-file PATH]
///
/// The i-th --sysfs-root, --robot and --name belong to the i-th robot; a robot without --robot
/// takes the world file's i-th `start` pose.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "ev3sim/drivers.hpp"
#include "ev3sim/geometry.hpp"

namespace ev3sim {

struct RobotOptions {
  std::string name;
  std::string root;           ///< the mount point of its tree
  std::optional<Pose> pose;   ///< from --robot (else the world's start pose)
};

struct SimOptions {
  std::string world;
  std::vector<RobotOptions> robots;
  double rate_hz = 100;       ///< how often the loop advances the clock
  double time_scale = 1;      ///< simulated seconds per real second
  Generation gen = Generation::Stretch;
  std::string snapshot;       ///< SVG written at exit, on SIGUSR1 and on `snapshot`
  std::string control;        ///< control FIFO (created if missing)
  std::string status;         ///< JSON status written at exit, on SIGUSR1 and on `status`
  double duration_s = 0;      ///< stop after this much simulated time (0: run until a signal)
  double battery_volts = 8.04;
  double battery_mah = 2000;
  std::uint64_t seed = 1;
  bool allow_other = false;
  int log_level = 2;
  std::string log_file;
  bool help = false;
};

/// Parses argv. Returns "" or the error (naming the bad argument).
std::string parse_sim_options(int argc, const char* const* argv, SimOptions& out);
/// The --help text.
std::string sim_usage();

}  // namespace ev3sim
