/// @file key_file.hpp
/// @brief The fleet key of signed mode (`--key-file FILE`, docs/protocol.md "Signed datagrams"):
///        read and checked once at start; the key's text never reaches a message, log or trace.
#pragma once

#include <string>

#include <ev3proto/auth.hpp>

namespace ev3io {

/// Reads the key file @p path into @p key: a regular file that neither group nor others may read,
/// holding 64 hex digits (a trailing newline allowed). "" or the error, naming the file and what is
/// wrong ("/etc/ev3/fleet.key: readable by group or others (mode 0644): chmod 600 it").
std::string load_key_file(const std::string& path, ev3proto::auth::Key& key);

}  // namespace ev3io
