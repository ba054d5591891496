// Datagrams as transcripts write them: `7->1 PING #12 WORKING` (sender->receiver, type, msgid, params).
// A param that is not a plain word is quoted ("wrong state"); the datagram inside a RELAY, an
// EPOCH_CMD or a REPORT is written in brackets ([1->9 PONG #31 5]); bytes that do not decode are written
// `!undecodable <reason> "<bytes>"`. parse_symbolic() reads the same form back (inputs of the
// transcripts), so every datagram of a transcript reads as what it means.
#pragma once

#include <cctype>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "ev3proto/messages.hpp"
#include "ev3proto/wire.hpp"

namespace ev3test {

namespace symbolic_detail {

inline bool plain(std::string_view p) {
  if (p.empty() || p[0] == '#' || p[0] == '[' || p[0] == '"' || p[0] == '!') return false;
  for (char ch : p) {
    const auto c = static_cast<unsigned char>(ch);
    if (!(std::isalnum(c) || c == '_' || c == '.' || c == '=' || c == '+' || c == '-' || c == '/' ||
          c == ',' || c == '%'))
      return false;
  }
  return true;
}

inline std::string quoted(std::string_view p) {
  std::string s = "\"";
  for (char ch : p) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '"' || c == '\\') {
      s += '\\';
      s += ch;
    } else if (c < 0x20 || c > 0x7E) {
      static const char kHex[] = "0123456789ABCDEF";
      s += "\\x";
      s += kHex[c >> 4];
      s += kHex[c & 15];
    } else {
      s += ch;
    }
  }
  return s + "\"";
}

/// True for the param that holds a whole datagram (RELAY's and EPOCH_CMD's second, REPORT's third).
inline bool holds_datagram(ev3proto::MsgType t, std::size_t i) {
  return (i == 1 && (t == ev3proto::MsgType::RELAY || t == ev3proto::MsgType::EPOCH_CMD)) ||
         (i == 2 && t == ev3proto::MsgType::REPORT);
}

}  // namespace symbolic_detail

/// The symbolic form of a decoded message.
inline std::string symbolic(const ev3proto::Message& m) {
  using namespace symbolic_detail;
  std::string s = std::to_string(m.sender) + "->" + std::to_string(m.receiver) + " ";
  const std::string_view name = ev3proto::to_string(m.type);
  s += name.empty() ? "TYPE" + std::to_string(static_cast<unsigned>(m.type)) : std::string(name);
  s += " #" + std::to_string(m.msgid);
  for (std::size_t i = 0; i < m.param_count(); ++i) {
    const std::string_view p = m.param(i);
    s += ' ';
    ev3proto::Message inner;
    if (holds_datagram(m.type, i) && ev3proto::decode(p, inner).ok())
      s += "[" + symbolic(inner) + "]";
    else
      s += plain(p) ? std::string(p) : quoted(p);
  }
  return s;
}

/// The symbolic form of datagram @p bytes.
inline std::string symbolic(std::string_view bytes) {
  ev3proto::Message m;
  const ev3proto::DecodeResult r = ev3proto::decode(bytes, m);
  if (!r.ok()) {
    std::string reason(ev3proto::to_string(r.reason));
    for (char& c : reason)
      if (c == ' ') c = '_';
    return "!undecodable " + reason + " " + symbolic_detail::quoted(bytes);
  }
  return symbolic(m);
}

namespace symbolic_detail {

struct Reader {
  std::string_view t;
  std::size_t i = 0;
  std::string error;

  void blanks() {
    while (i < t.size() && t[i] == ' ') ++i;
  }
  bool fail(const std::string& why) {
    if (error.empty()) error = why + " at column " + std::to_string(i + 1) + " of '" + std::string(t) + "'";
    return false;
  }
  bool number(std::uint32_t& v) {
    const std::size_t b = i;
    std::uint64_t n = 0;
    while (i < t.size() && std::isdigit(static_cast<unsigned char>(t[i])) && n <= 0xFFFFFFFFu)
      n = n * 10 + static_cast<unsigned>(t[i++] - '0');
    if (i == b || n > 0xFFFFFFFFu) return fail("expected a number");
    v = static_cast<std::uint32_t>(n);
    return true;
  }
  bool word(std::string& w) {
    const std::size_t b = i;
    while (i < t.size() && t[i] != ' ' && t[i] != ']') ++i;
    if (i == b) return fail("expected a word");
    w = std::string(t.substr(b, i - b));
    return true;
  }
  bool quoted_param(std::string& out) {
    ++i;  // "
    while (i < t.size() && t[i] != '"') {
      if (t[i] == '\\' && i + 1 < t.size()) {
        if (t[i + 1] == 'x' && i + 3 < t.size()) {
          out += static_cast<char>(std::stoi(std::string(t.substr(i + 2, 2)), nullptr, 16));
          i += 4;
        } else {
          out += t[i + 1];
          i += 2;
        }
      } else {
        out += t[i++];
      }
    }
    if (i == t.size()) return fail("unterminated quote");
    ++i;
    return true;
  }
  /// SRC->DST TYPE #MSGID PARAM... (up to the end or a closing bracket).
  bool datagram(std::string& bytes) {
    blanks();
    std::uint32_t src = 0, dst = 0, msgid = 0;
    if (!number(src)) return false;
    if (t.substr(i, 2) != "->") return fail("expected ->");
    i += 2;
    if (!number(dst)) return false;
    blanks();
    std::string name;
    if (!word(name)) return false;
    std::uint8_t type = 0;
    for (const ev3proto::MessageSpec& s : ev3proto::kMessageTable)
      if (s.name == name) type = s.type;
    if (type == 0) return fail("unknown message type " + name);
    blanks();
    if (i >= t.size() || t[i] != '#') return fail("expected #msgid");
    ++i;
    if (!number(msgid)) return false;
    std::vector<std::string> params;
    for (;;) {
      blanks();
      if (i >= t.size() || t[i] == ']') break;
      std::string p;
      if (t[i] == '"') {
        if (!quoted_param(p)) return false;
      } else if (t[i] == '[') {
        ++i;
        if (!datagram(p)) return false;
        if (i >= t.size() || t[i] != ']') return fail("expected ]");
        ++i;
      } else if (!word(p)) {
        return false;
      }
      params.push_back(std::move(p));
    }
    if (src > 0xFFFF || dst > 0xFFFF) return fail("id above 65535");
    std::vector<std::string_view> views(params.begin(), params.end());
    char buf[ev3proto::kMaxDatagram];
    const ev3proto::EncodeResult r =
        ev3proto::encode_parts(static_cast<std::uint16_t>(src), static_cast<std::uint16_t>(dst), msgid, type,
                               views.data(), views.size(), buf, sizeof buf);
    if (!r.ok()) return fail("does not encode: " + std::string(ev3proto::to_string(r.reason)));
    bytes.assign(buf, r.size);
    return true;
  }
};

}  // namespace symbolic_detail

/// The wire bytes of symbolic datagram @p text; false (with @p error) when it is malformed.
inline bool parse_symbolic(std::string_view text, std::string& bytes, std::string& error) {
  symbolic_detail::Reader r;
  r.t = text;
  std::string out;
  if (!r.datagram(out)) {
    error = r.error;
    return false;
  }
  r.blanks();
  if (r.i != text.size()) {
    error = "trailing text in '" + std::string(text) + "'";
    return false;
  }
  bytes = std::move(out);
  return true;
}

/// True when @p text looks like a symbolic datagram (it has "->" before the first blank).
/// The words of a transcript line from the @p first one on, joined by single spaces ("error" when
/// there are none): the free text at the end of a command (a failure's reason).
inline std::string words_from(const std::vector<std::string>& w, std::size_t first) {
  std::string out;
  for (std::size_t i = first; i < w.size(); ++i) out += (out.empty() ? "" : " ") + w[i];
  return out.empty() ? "error" : out;
}

inline bool is_symbolic(std::string_view text) {
  const std::size_t arrow = text.find("->");
  return arrow != std::string_view::npos && arrow < text.find(' ');
}

}  // namespace ev3test
