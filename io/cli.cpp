#include "ev3io/cli.hpp"

#include <cmath>
#include <cstdlib>
#include <cstring>

namespace ev3io {

std::string ParsedArgs::get(const std::string& name, const std::string& def) const {
  auto it = values.find(name);
  return it == values.end() || it->second.empty() ? def : it->second.back();
}

namespace {
const OptionSpec* find_spec(const std::vector<OptionSpec>& specs, std::string_view name) {
  for (const OptionSpec& s : specs)
    if (s.name == name) return &s;
  return nullptr;
}
std::string thesis_key(std::string_view key) {
  std::string k(key);
  for (char& c : k)
    if (c == '_') c = '-';
  if (k == "loglevel") k = "log-level";
  if (k == "logfile") k = "log-file";
  return k;
}
}  // namespace

std::string parse_args(int argc, const char* const* argv, const std::vector<OptionSpec>& specs,
                       std::string_view role_word, ParsedArgs& out) {
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == "-h" || arg == "--help" || arg == "help") {
      out.help = true;
      continue;
    }
    std::string name;
    std::string value;
    bool has_value = false;
    bool thesis = false;
    if (arg.size() > 2 && arg.substr(0, 2) == "--") {
      const std::string_view body = arg.substr(2);
      const std::size_t eq = body.find('=');
      name = std::string(body.substr(0, eq));
      if (eq != std::string_view::npos) {
        value = std::string(body.substr(eq + 1));
        has_value = true;
      }
    } else if (!arg.empty() && arg[0] != '-' && arg.find('=') != std::string_view::npos) {
      const std::size_t eq = arg.find('=');
      name = thesis_key(arg.substr(0, eq));
      value = std::string(arg.substr(eq + 1));
      has_value = true;
      thesis = true;
    } else if (i == 1 && !role_word.empty() && arg == role_word) {
      continue;
    } else {
      return "unexpected argument '" + std::string(arg) + "'";
    }
    const OptionSpec* s = find_spec(specs, name);
    if (s == nullptr)
      return "unknown " + std::string(thesis ? "setting '" : "flag '--") + name + "'";
    if (s->metavar.empty()) {
      if (has_value && !thesis) return "flag '--" + name + "' takes no value";
      if (thesis && value != "1" && value != "true" && value != "yes")
        return "flag '" + name + "' takes no value";
      value.clear();
    } else if (!has_value) {
      if (i + 1 >= argc) return "flag '--" + name + "' needs a value (" + s->metavar + ")";
      value = argv[++i];
    }
    auto& v = out.values[name];
    if (!s->repeatable) v.clear();
    v.push_back(value);
  }
  return {};
}

std::string usage(const std::string& synopsis, const std::vector<OptionSpec>& specs) {
  std::string u = synopsis + "\n\nOptions:\n";
  for (const OptionSpec& s : specs) {
    std::string left = "  --" + s.name + (s.metavar.empty() ? "" : " " + s.metavar);
    if (left.size() < 30) left.append(30 - left.size(), ' ');
    u += left + " " + s.help + (s.repeatable ? " (repeatable)" : "") + "\n";
  }
  u += "  --help                       this text\n";
  return u;
}

bool to_uint(std::string_view s, std::uint64_t lo, std::uint64_t hi, std::uint64_t& out) noexcept {
  if (s.empty() || s.size() > 19 || (s.size() > 1 && s[0] == '0')) return false;
  std::uint64_t v = 0;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + static_cast<std::uint64_t>(c - '0');
  }
  if (v < lo || v > hi) return false;
  out = v;
  return true;
}

bool to_double(std::string_view s, double lo, double hi, double& out) noexcept {
  if (s.empty() || s.size() > 40) return false;
  char buf[48];
  std::memcpy(buf, s.data(), s.size());
  buf[s.size()] = '\0';
  for (std::size_t i = 0; i < s.size(); ++i) {
    const char c = buf[i];
    if (!((c >= '0' && c <= '9') || c == '.' || c == 'e' || c == 'E' || c == '-' || c == '+'))
      return false;  // no "inf", "nan", hex floats or spaces
  }
  char* end = nullptr;
  const double v = std::strtod(buf, &end);
  if (end != buf + s.size() || !std::isfinite(v) || v < lo || v > hi) return false;
  out = v;
  return true;
}

std::vector<OptionSpec> common_specs() {
  return {
      {"port", "N", "UDP port to bind (default 12345; 0 = any free port)", false},
      {"bind", "ADDR", "address to bind (default 0.0.0.0)", false},
      {"broadcast", "HOST:PORT", "where broadcast messages go (default 255.255.255.255:12345)", true},
      {"log-level", "0..4", "0 none, 1 error, 2 info (default), 3 debug, 4 verbose", false},
      {"log-file", "PATH", "log to PATH (appending) instead of stderr", false},
      {"trace", "FILE", "NDJSON trace of the spec actions taken", false},
      {"key-file", "FILE", "signed mode: sign every datagram with the key in FILE (64 hex digits, mode 0600) "
                           "and take only datagrams signed with it", false},
      {"fault-loss", "PCT", "tests: drop PCT % of outgoing copies", false},
      {"fault-dup", "PCT", "tests: duplicate PCT % of outgoing copies", false},
      {"fault-reorder", "PCT", "tests: hold back PCT % of copies so later ones overtake", false},
      {"fault-delay-ms", "N", "tests: delay every outgoing copy by N ms", false},
      {"fault-seed", "S", "tests: seed of the fault schedule (default 1)", false},
  };
}

std::string read_uint(const ParsedArgs& a, const std::string& name, std::uint64_t lo, std::uint64_t hi,
                      std::uint64_t& out) {
  if (!a.has(name)) return {};
  const std::string v = a.get(name);
  if (!to_uint(v, lo, hi, out))
    return "bad value for --" + name + ": '" + v + "' (expected a whole number " + std::to_string(lo) +
           ".." + std::to_string(hi) + ")";
  return {};
}

std::string read_common(const ParsedArgs& a, CommonOptions& o) {
  std::uint64_t v = o.port;
  std::string e = read_uint(a, "port", 0, 65535, v);
  if (!e.empty()) return e;
  o.port = static_cast<std::uint16_t>(v);
  if (a.has("bind")) {
    o.bind_str = a.get("bind");
    if (!parse_address(o.bind_str, o.bind_addr))
      return "bad value for --bind: '" + o.bind_str + "' (expected an IPv4 address)";
  }
  o.broadcast.clear();
  if (a.has("broadcast")) {
    for (const std::string& s : a.values.at("broadcast")) {
      Endpoint ep;
      if (!parse_endpoint(s, ep))
        return "bad value for --broadcast: '" + s + "' (expected HOST:PORT, e.g. 127.0.0.1:12345)";
      o.broadcast.push_back(ep);
    }
  } else {
    Endpoint ep;
    parse_endpoint("255.255.255.255:12345", ep);
    o.broadcast.push_back(ep);
  }
  v = static_cast<std::uint64_t>(o.log_level);
  e = read_uint(a, "log-level", 0, 4, v);
  if (!e.empty()) return e;
  o.log_level = static_cast<int>(v);
  o.log_file = a.get("log-file");
  if (a.has("log-file") && o.log_file.empty()) return "bad value for --log-file: empty path";
  o.trace_file = a.get("trace");
  if (a.has("trace") && o.trace_file.empty()) return "bad value for --trace: empty path";
  o.key_file = a.get("key-file");
  if (a.has("key-file") && o.key_file.empty()) return "bad value for --key-file: empty path";
  const char* pct[] = {"fault-loss", "fault-dup", "fault-reorder"};
  double* dst[] = {&o.faults.loss, &o.faults.dup, &o.faults.reorder};
  for (int i = 0; i < 3; ++i) {
    if (!a.has(pct[i])) continue;
    const std::string s = a.get(pct[i]);
    if (!to_double(s, 0, 100, *dst[i]))
      return std::string("bad value for --") + pct[i] + ": '" + s + "' (expected a percentage 0..100)";
  }
  v = o.faults.delay_ms;
  e = read_uint(a, "fault-delay-ms", 0, 60000, v);
  if (!e.empty()) return e;
  o.faults.delay_ms = v;
  v = o.faults.seed;
  e = read_uint(a, "fault-seed", 0, UINT64_MAX / 10, v);
  if (!e.empty()) return e;
  o.faults.seed = v;
  return {};
}

}  // namespace ev3io
