/// @file state_file.hpp
/// @brief Small stable-storage files of the programs (the agent's election state, the master's
///        ids / msgids / epoch / membership): `key=value` lines, written atomically (temp file,
///        fsync, rename, fsync of the directory) so a crash leaves the old or the new file.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace ev3io {

/// Writes @p kv to @p path atomically. False with a message in @p err.
bool write_state_file(const std::string& path, const std::map<std::string, std::string>& kv, std::string& err);

/// Reads @p path into @p kv. False when it does not exist or cannot be read (@p err says which;
/// empty when it does not exist).
bool read_state_file(const std::string& path, std::map<std::string, std::string>& kv, std::string& err);

/// Parses a membership as the state files keep it: agent ids 2..49999 separated by commas, each at
/// most once ("" is the empty list). False (and @p out cleared) when an entry is not one.
bool parse_id_list(const std::string& s, std::vector<std::uint16_t>& out);

/// The other way round: "7,8,9" ("" for none).
std::string format_id_list(const std::vector<std::uint16_t>& ids);

/// The membership a state file keeps (docs/election.md section 6): the list, the epoch
/// that published it, and (the agent's) floor.
struct StoredMembership {
  std::vector<std::uint16_t> members; ///< `members`: agent ids 2..49999, at most kMaxMembership.
  std::uint32_t members_epoch = 0;    ///< `members_epoch`: 0 (none known) .. epoch; >= 1 with members.
  std::uint32_t floor = 0;            ///< `floor` (the agent's): members_epoch .. epoch.
};

/// Reads and checks the membership of state file @p kv whose epoch is @p epoch, by one rule for
/// ev3-agent (@p with_floor) and ev3-master (no floor): a key that is absent is empty / 0 (a file
/// without them knows no membership). False with the bad key named in @p err
/// ("members_epoch: 7 is above epoch 5").
bool read_membership(const std::map<std::string, std::string>& kv, std::uint32_t epoch, bool with_floor,
                     StoredMembership& out, std::string& err);

/// Appends the lines of text file @p path (without their newlines) to @p lines: stdio, no iostreams
/// (the EV3 binary carries none). False when it does not exist or cannot be read (@p err says
/// which; empty when it does not exist).
bool read_lines(const std::string& path, std::vector<std::string>& lines, std::string& err);

}  // namespace ev3io
