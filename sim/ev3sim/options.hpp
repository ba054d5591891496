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

// --- ev3-sim exec (docs/devices.md, "Running a brick's program") ------------------------------
//
//     ev3-sim exec (--robot N|NAME | --sysfs-root DIR | both) -- COMMAND [ARGS]...
//
// Runs COMMAND with one robot's tree of a running ev3-sim in place of /sys/class (and
// /sys/devices, where the class directories' links lead). Each tree ev3-sim mounts carries its
// robot in the mount's source: "ev3-sim:N:NAME" (N the robot's place on ev3-sim's command line,
// from 1), which exec finds in /proc/self/mountinfo.

struct ExecOptions {
  std::string robot;                  ///< --robot: a number (the N-th robot) or a name; "" if not given
  std::string root;                   ///< --sysfs-root: the tree's mount point; "" if not given
  std::vector<std::string> command;   ///< after "--"
  bool help = false;
};

/// Parses the arguments after "exec" (argv[0] is "exec"). Returns "" or the error.
std::string parse_exec_options(int argc, const char* const* argv, ExecOptions& out);
/// The exec --help text.
std::string exec_usage();

/// The FUSE mount source of robot @p index (from 1) called @p name.
std::string mount_source(std::size_t index, const std::string& name);

/// A robot's tree that a running ev3-sim serves, as /proc/self/mountinfo shows it.
struct SimMount {
  std::string dir;   ///< the mount point
  long index = 0;    ///< the robot's place on its ev3-sim's command line, from 1
  std::string name;  ///< the robot's name
};
/// The ev3-sim mounts (file system type fuse.ev3-sim) listed in @p mountinfo, in its order.
std::vector<SimMount> parse_sim_mounts(const std::string& mountinfo);
/// Picks the mount that @p opt names among @p mounts; @p real_root is --sysfs-root with its
/// symlinks resolved ("" when not given). Returns "" and sets @p out, or the error (naming what
/// runs).
std::string pick_sim_mount(const std::vector<SimMount>& mounts, const ExecOptions& opt,
                           const std::string& real_root, SimMount& out);

}  // namespace ev3sim
