/// @file json.hpp
/// @brief The one JSON string escaper of the tree: the NDJSON trace, the programs' driver mode and
///        status JSON, and the simulator's status all write strings through it.
///
/// Strings are bytes (datagrams may hold any byte): '"' and '\\' get a backslash, bytes below 0x20
/// and above 0x7E are written as \u00XX (so a reader maps each back to one byte). Host-side: this
/// header uses std::string; the agent core never includes it.
#pragma once

#include <string>
#include <string_view>

namespace ev3proto {

/// Appends @p s to @p out as a JSON string literal.
inline void json_string(std::string& out, std::string_view s) {
  static constexpr char kHex[] = "0123456789abcdef";
  out += '"';
  for (char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += ch;
    } else if (c < 0x20 || c > 0x7E) {
      out += "\\u00";
      out += kHex[c >> 4];
      out += kHex[c & 0xF];
    } else {
      out += ch;
    }
  }
  out += '"';
}

/// @p s as a JSON string literal.
inline std::string json_quote(std::string_view s) {
  std::string out;
  out.reserve(s.size() + 2);
  json_string(out, s);
  return out;
}

/// @p items as a JSON array of strings: ["left motor","right motor"].
template <class Strings>
std::string json_list(const Strings& items) {
  std::string out = "[";
  for (const auto& s : items) {
    if (out.size() > 1) out += ',';
    json_string(out, s);
  }
  out += ']';
  return out;
}

}  // namespace ev3proto
