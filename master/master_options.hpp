/// @file options.hpp
/// @brief ev3-master's command line (docs/programs.md).
#pragma once

#include <string>

#include <ev3proto/master.hpp>

#include "ev3io/cli.hpp"

namespace ev3master {

struct MasterOptions {
  ev3io::CommonOptions common;
  ev3proto::Timers timers;       ///< drop (--agent-timeout-ms), resend (--resend-ms)
  std::uint32_t max_resends = 10;
  std::string status_json;       ///< --status-json FILE
  std::string script;            ///< --script FILE
  bool election = false;         ///< --election: LEADER heartbeats, epochs, relay routes (MasterConfig::election)
  std::string state_file;        ///< --state-file FILE: next id, msgid, epoch, members across restarts
  std::string record;            ///< --record FILE: the record of reports, appended, read back at a restart
  std::string control;           ///< --control PATH: the console language over a Unix socket
  std::string control_group;     ///< --control-group GROUP: the socket 0660 for GROUP (else 0600)
  bool json = false;             ///< --json: the control socket answers in JSON
  std::string db;                ///< --db FILE: the mission's record in SQLite (docs/record.md)
};

using ParseOutcome = ev3io::ParseOutcome;

/// Parses the command line; @p message gets the usage (help) or the error naming the bad flag.
ParseOutcome parse_master_options(int argc, const char* const* argv, MasterOptions& out, std::string& message);

}  // namespace ev3master
