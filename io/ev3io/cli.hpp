/// @file cli.hpp
/// @brief Command-line parsing shared by ev3-agent and ev3-master: `--flag VALUE`, `--flag=VALUE`
///        and the thesis' form `key=value` (`ev3-agent port=12233 model=A loglevel=2`), typed value
///        checks, usage text, and the flags both programs take (port, bind, broadcast, logging,
///        trace, fault injection, signed mode's key file).
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "ev3io/fault.hpp"
#include "ev3io/udp.hpp"

namespace ev3io {

/// What a command line asks for: run the program, print its usage (message: the usage), or stop
/// with an error (message: the error naming the bad flag).
enum class ParseOutcome { run, help, error };

/// One flag a program accepts.
struct OptionSpec {
  std::string name;     ///< Without the dashes ("port").
  std::string metavar;  ///< Value placeholder ("N"); empty for a flag without a value.
  std::string help;     ///< One line.
  bool repeatable = false; ///< May be given more than once (values accumulate).
};

/// Flags as given: name -> values in order (a flag without value maps to {""}).
struct ParsedArgs {
  std::map<std::string, std::vector<std::string>> values;
  bool help = false;
  /// True when @p name was given.
  bool has(const std::string& name) const { return values.count(name) != 0; }
  /// The last value of @p name (or @p def).
  std::string get(const std::string& name, const std::string& def = {}) const;
};

/// Parses @p argv. Accepts `--name VALUE`, `--name=VALUE`, `name=VALUE` (thesis form; `_` may stand
/// for `-`, and `loglevel` for `log-level`), `-h`/`--help`, and @p role_word as a bare first word
/// (the thesis' `ev3dev agent ...`). Returns "" or an error naming the bad argument.
std::string parse_args(int argc, const char* const* argv, const std::vector<OptionSpec>& specs,
                       std::string_view role_word, ParsedArgs& out);

/// Usage text: @p synopsis, then one line per flag.
std::string usage(const std::string& synopsis, const std::vector<OptionSpec>& specs);

/// A canonical unsigned decimal in [lo, hi].
bool to_uint(std::string_view s, std::uint64_t lo, std::uint64_t hi, std::uint64_t& out) noexcept;
/// A finite decimal number in [lo, hi] ("2", "0.5", "1e3").
bool to_double(std::string_view s, double lo, double hi, double& out) noexcept;

/// The flags both programs take.
struct CommonOptions {
  std::uint16_t port = 12345;
  std::uint32_t bind_addr = 0;  ///< 0.0.0.0
  std::string bind_str = "0.0.0.0";
  std::vector<Endpoint> broadcast;  ///< Where broadcasts go.
  int log_level = 2;
  std::string log_file;
  std::string trace_file;
  std::string key_file;  ///< Signed mode's key file; "" = unsigned.
  FaultConfig faults;
};

/// The specs of the common flags.
std::vector<OptionSpec> common_specs();
/// Reads the common flags out of @p a; "" or the error naming the flag.
std::string read_common(const ParsedArgs& a, CommonOptions& o);

/// Reads flag @p name as an unsigned in [lo, hi] into @p out when given; "" or the error.
std::string read_uint(const ParsedArgs& a, const std::string& name, std::uint64_t lo, std::uint64_t hi,
                      std::uint64_t& out);

}  // namespace ev3io
