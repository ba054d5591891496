/// @file options.hpp
/// @brief ev3-agent's command line (docs/programs.md), in both forms: `--port 12233 --model A` and
///        the thesis' `port=12233 model=A loglevel=2`.
#pragma once

#include <cstdint>
#include <string>

#include <ev3proto/robot/model.hpp>
#include <ev3proto/robot_runtime.hpp>
#include <ev3proto/timers.hpp>

#include "ev3io/cli.hpp"

namespace ev3agent {

struct AgentOptions {
  ev3io::CommonOptions common;
  std::string model = "A";
  std::string sysfs_root = "/sys";  ///< --sysfs-root DIR: ev3dev's tree (a brick's /sys, or ev3-sim's mount)
  ev3proto::robot::PortMap ports;    ///< --ports role=port,...: model A's ports
  ev3proto::Millis tick_ms = 20;     ///< --tick-ms N: the control tick while the motors may move
  /// --watchdog-ms N: wheels held this long after the last contact with a master (0: off)
  ev3proto::Millis watchdog_ms = ev3proto::robot::RuntimeConfig{}.watchdog_ms;
  ev3proto::Timers timers;  ///< sync, heartbeat, loss (--master-timeout-ms), paused
  bool election = false;    ///< --election: relay and election on (AgentConfig::election)
  std::uint32_t score = 0xFFFFFFFFu;  ///< --score N (default: computed from the capabilities)
  std::string state_dir;    ///< --state-dir DIR: epoch and votedFor on disk ("" = in memory only)
  std::string master_script;  ///< --master-script FILE: console commands run when elected master
  std::size_t report_buffer = 0;  ///< --report-buffer N: reports kept until the PC records them (0 = the core's 1024)
  ev3proto::robot::Pose pose;     ///< --pose X,Y,HEADING (cm, cm, degrees): where the robot starts, for odometry
  ev3proto::Millis pose_ms = ev3proto::robot::RuntimeConfig{}.pose_ms;  ///< --pose-ms N: pose report period (0: off)
};

using ParseOutcome = ev3io::ParseOutcome;

/// Parses the command line; @p message gets the usage (help) or the error naming the bad flag.
ParseOutcome parse_agent_options(int argc, const char* const* argv, AgentOptions& out, std::string& message);

}  // namespace ev3agent
