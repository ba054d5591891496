/// @file state_file.hpp
/// @brief Small stable-storage files of the programs (the agent's election state, the master's
///        ids / msgids / epoch / membership): written atomically (temp file, fsync, rename, fsync
///        of the directory) so a crash leaves the old or the new file. Their text and its rules
///        are the library's (ev3proto/durable.hpp).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace ev3io {

/// Writes @p text to @p path atomically. False with a message in @p err.
bool write_state_file(const std::string& path, std::string_view text, std::string& err);

/// Reads all of @p path into @p text. False when it does not exist or cannot be read (@p err says
/// which; empty when it does not exist).
bool read_state_file(const std::string& path, std::string& text, std::string& err);

/// Appends the lines of text file @p path (without their newlines) to @p lines: stdio, no iostreams
/// (the EV3 binary carries none). False when it does not exist or cannot be read (@p err says
/// which; empty when it does not exist).
bool read_lines(const std::string& path, std::vector<std::string>& lines, std::string& err);

}  // namespace ev3io
