// ev3-codec: line-oriented front end of libev3proto's codec, for differential tests and debugging.
// See `ev3-codec --help` (kUsage below) for the exact interface.
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <string>
#include <string_view>
#include <vector>

#include "ev3proto/wire.hpp"

namespace {

constexpr const char* kUsage =
    "usage: ev3-codec [decode|encode] [--help]\n"
    "Reads stdin line by line and writes exactly one line per input line to stdout (flushed).\n"
    "\n"
    "ev3-codec decode   (the default)\n"
    "  input:  the datagram bytes in lower-case hex; an empty line is the empty datagram.\n"
    "  output: ok <sender> <receiver> <msgid> <type> <nparams> <p1> ... <pn> = <hex of encode(message)>\n"
    "          each pi is the unescaped param in lower-case hex, or - if it is empty;\n"
    "       or err <field> <reason>          e.g. err 4 bad escape\n"
    "       or bad-input <explanation>       the line is not valid hex\n"
    "\n"
    "ev3-codec encode\n"
    "  input:  <sender> <receiver> <msgid> <type> <p1> ... <pn>\n"
    "          numbers in decimal (may exceed the field ranges), params in lower-case hex, - for empty.\n"
    "  output: ok <hex datagram>\n"
    "       or err <field> <reason>          the field decode would report; too long is field 0\n"
    "       or bad-input <explanation>\n"
    "\n"
    "Reasons: empty, too long, too few fields, bad number, out of range, unknown type, bad escape,\n"
    "non-printable byte, too many params. Exit status 0 at end of input, 2 on a bad command line.\n";

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// Decodes hex text into bytes; returns an explanation on failure, "" on success.
std::string from_hex(std::string_view text, std::string& out) {
  out.clear();
  if (text.size() % 2 != 0) return "odd number of hex digits";
  out.reserve(text.size() / 2);
  for (std::size_t i = 0; i < text.size(); i += 2) {
    const int hi = hex_digit(text[i]);
    const int lo = hex_digit(text[i + 1]);
    if (hi < 0 || lo < 0) return "not a hex digit at offset " + std::to_string(hi < 0 ? i : i + 1);
    out.push_back(static_cast<char>(hi * 16 + lo));
  }
  return {};
}

void append_hex(std::string& out, std::string_view bytes) {
  static constexpr char kHex[] = "0123456789abcdef";
  for (char ch : bytes) {
    const auto c = static_cast<unsigned char>(ch);
    out.push_back(kHex[c >> 4]);
    out.push_back(kHex[c & 0x0Fu]);
  }
}

std::string error_line(ev3proto::Reason r, unsigned field) {
  return "err " + std::to_string(field) + " " + std::string(ev3proto::to_string(r));
}

std::string decode_line(const std::string& line) {
  std::string bytes;
  const std::string why = from_hex(line, bytes);
  if (!why.empty()) return "bad-input " + why;
  ev3proto::Message m;
  const ev3proto::DecodeResult r = ev3proto::decode(bytes, m);
  if (!r.ok()) return error_line(r.reason, r.field);
  std::string out = "ok " + std::to_string(m.sender) + " " + std::to_string(m.receiver) + " " +
                    std::to_string(m.msgid) + " " + std::to_string(static_cast<unsigned>(m.type)) + " " +
                    std::to_string(m.param_count());
  for (std::size_t i = 0; i < m.param_count(); ++i) {
    out.push_back(' ');
    if (m.param(i).empty())
      out.push_back('-');
    else
      append_hex(out, m.param(i));
  }
  char buf[ev3proto::kMaxDatagram];
  const ev3proto::EncodeResult e = ev3proto::encode(m, buf, sizeof buf);
  out += " = ";
  if (e.ok())
    append_hex(out, std::string_view(buf, e.size));
  else  // cannot happen for a decoded message; reported loudly so a differential test catches it
    out += "ENCODE-FAILED " + error_line(e.reason, e.field);
  return out;
}

// A decimal number from the encode input: its canonical digit count and its value saturated at
// UINT64_MAX (enough to compare with any field maximum).
struct Number {
  std::size_t digits = 0;
  std::uint64_t value = 0;
};

bool parse_decimal(std::string_view s, Number& n) {
  if (s.empty()) return false;
  std::size_t k = 0;
  while (k + 1 < s.size() && s[k] == '0') ++k;  // leading zeros do not count towards the length
  n.digits = s.size() - k;
  n.value = 0;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
    const auto d = static_cast<std::uint64_t>(c - '0');
    n.value = n.value > (UINT64_MAX - d) / 10u ? UINT64_MAX : n.value * 10u + d;
  }
  return true;
}

std::string encode_line(const std::string& line) {
  std::vector<std::string_view> words;
  std::string_view rest(line);
  while (!rest.empty()) {
    const std::size_t sp = rest.find(' ');
    const std::string_view w = rest.substr(0, sp);
    if (w.empty()) return "bad-input empty word (two spaces in a row, or a leading/trailing space)";
    words.push_back(w);
    if (sp == std::string_view::npos) break;
    rest.remove_prefix(sp + 1);
    if (rest.empty()) return "bad-input trailing space";
  }
  if (words.size() < 4) return "bad-input need <sender> <receiver> <msgid> <type> [params...]";
  Number num[4];
  static constexpr const char* kNames[4] = {"sender", "receiver", "msgid", "type"};
  for (std::size_t k = 0; k < 4; ++k)
    if (!parse_decimal(words[k], num[k])) return std::string("bad-input ") + kNames[k] + " is not a decimal number";
  std::vector<std::string> params(words.size() - 4);
  for (std::size_t i = 0; i < params.size(); ++i) {
    const std::string_view w = words[4 + i];
    if (w == "-") continue;
    const std::string why = from_hex(w, params[i]);
    if (!why.empty()) return "bad-input param " + std::to_string(i + 1) + ": " + why;
  }
  // Checks in decode's order: length first, then the header fields, then (in the library) the rest.
  std::size_t size = num[0].digits + num[1].digits + num[2].digits + num[3].digits + 3;
  for (const std::string& p : params) size += 1 + ev3proto::escaped_size(p);
  if (size > ev3proto::kMaxDatagram) return error_line(ev3proto::Reason::too_long, 0);
  static constexpr std::uint64_t kMax[4] = {0xFFFFu, 0xFFFFu, 0xFFFFFFFFu, 0xFFu};
  for (unsigned k = 0; k < 4; ++k)
    if (num[k].value > kMax[k] || (k == 3 && num[k].value == 0))
      return error_line(ev3proto::Reason::out_of_range, k);
  std::vector<std::string_view> views(params.begin(), params.end());
  char buf[ev3proto::kMaxDatagram];
  const ev3proto::EncodeResult e = ev3proto::encode_parts(
      static_cast<std::uint16_t>(num[0].value), static_cast<std::uint16_t>(num[1].value),
      static_cast<std::uint32_t>(num[2].value), static_cast<std::uint8_t>(num[3].value), views.data(),
      views.size(), buf, sizeof buf);
  if (!e.ok()) return error_line(e.reason, e.field);
  std::string out = "ok ";
  append_hex(out, std::string_view(buf, e.size));
  return out;
}

} // namespace

int main(int argc, char** argv) {
  bool encode_mode = false;
  bool mode_given = false;
  for (int i = 1; i < argc; ++i) {
    const std::string_view a(argv[i]);
    if (a == "--help" || a == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    if ((a == "decode" || a == "encode") && !mode_given) {
      encode_mode = a == "encode";
      mode_given = true;
      continue;
    }
    std::fprintf(stderr, "ev3-codec: unexpected argument '%s'\n%s", argv[i], kUsage);
    return 2;
  }
  std::ios::sync_with_stdio(false);
  std::string line;
  while (std::getline(std::cin, line)) {
    const std::string out = encode_mode ? encode_line(line) : decode_line(line);
    std::fwrite(out.data(), 1, out.size(), stdout);
    std::fputc('\n', stdout);
    std::fflush(stdout);
  }
  return 0;
}
