// A minimal JSON reader/writer for the driver mode (docs/driver.md): one NDJSON input line is one
// object. Only what the driver needs: objects, arrays, strings (with \uXXXX for bytes < 0x100),
// integers, booleans, null. Shared by ev3-agent --driver and ev3-master --driver.
#pragma once

#include <ev3proto/json.hpp>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace ev3prog {

/// A parsed JSON value.
struct Json {
  enum class Kind { null, boolean, number, string, array, object } kind = Kind::null;
  bool b = false;
  long long n = 0;
  std::string s;
  std::vector<Json> a;
  std::map<std::string, Json> o;

  bool has(const std::string& k) const { return kind == Kind::object && o.count(k) != 0; }
  const Json& operator[](const std::string& k) const {
    static const Json none;
    auto it = o.find(k);
    return (kind == Kind::object && it != o.end()) ? it->second : none;
  }
  long long num(long long dflt = 0) const { return kind == Kind::number ? n : dflt; }
  std::string str(std::string dflt = {}) const { return kind == Kind::string ? s : dflt; }
  bool boolean(bool dflt = false) const { return kind == Kind::boolean ? b : dflt; }
};

/// Parses @p text into @p out; on error returns false and sets @p err.
inline bool parse_json(std::string_view text, Json& out, std::string& err) {
  std::size_t i = 0;
  auto ws = [&] {
    while (i < text.size() && (text[i] == ' ' || text[i] == '\t' || text[i] == '\r' || text[i] == '\n')) ++i;
  };
  auto fail = [&](const char* what) {
    err = std::string(what) + " at offset " + std::to_string(i);
    return false;
  };
  // Recursive lambda via std::function-free helper struct.
  struct P {
    std::string_view t;
    std::size_t& i;
    std::string& err;
    int depth = 0;
    void ws() {
      while (i < t.size() && (t[i] == ' ' || t[i] == '\t' || t[i] == '\r' || t[i] == '\n')) ++i;
    }
    bool fail(const char* what) {
      err = std::string(what) + " at offset " + std::to_string(i);
      return false;
    }
    bool str(std::string& s) {
      if (i >= t.size() || t[i] != '"') return fail("expected a string");
      ++i;
      while (i < t.size() && t[i] != '"') {
        char c = t[i++];
        if (c != '\\') {
          s += c;
          continue;
        }
        if (i >= t.size()) return fail("bad escape");
        char e = t[i++];
        switch (e) {
          case '"': s += '"'; break;
          case '\\': s += '\\'; break;
          case '/': s += '/'; break;
          case 'n': s += '\n'; break;
          case 'r': s += '\r'; break;
          case 't': s += '\t'; break;
          case 'b': s += '\b'; break;
          case 'f': s += '\f'; break;
          case 'u': {
            if (i + 4 > t.size()) return fail("bad \\u escape");
            unsigned v = 0;
            for (int k = 0; k < 4; ++k) {
              char h = t[i++];
              v <<= 4;
              if (h >= '0' && h <= '9') v |= static_cast<unsigned>(h - '0');
              else if (h >= 'a' && h <= 'f') v |= static_cast<unsigned>(h - 'a' + 10);
              else if (h >= 'A' && h <= 'F') v |= static_cast<unsigned>(h - 'A' + 10);
              else return fail("bad \\u escape");
            }
            if (v > 0xFF) return fail("\\u escape above \\u00ff (strings are bytes)");
            s += static_cast<char>(v);
            break;
          }
          default: return fail("bad escape");
        }
      }
      if (i >= t.size()) return fail("unterminated string");
      ++i;
      return true;
    }
    bool value(Json& v) {
      if (++depth > 32) return fail("nested too deeply");
      ws();
      if (i >= t.size()) return fail("unexpected end");
      const char c = t[i];
      bool ok = true;
      if (c == '{') {
        v.kind = Json::Kind::object;
        ++i;
        ws();
        if (i < t.size() && t[i] == '}') {
          ++i;
        } else {
          for (;;) {
            ws();
            std::string k;
            if (!str(k)) return false;
            ws();
            if (i >= t.size() || t[i] != ':') return fail("expected ':'");
            ++i;
            Json item;
            if (!value(item)) return false;
            v.o[k] = std::move(item);
            ws();
            if (i < t.size() && t[i] == ',') { ++i; continue; }
            if (i < t.size() && t[i] == '}') { ++i; break; }
            return fail("expected ',' or '}'");
          }
        }
      } else if (c == '[') {
        v.kind = Json::Kind::array;
        ++i;
        ws();
        if (i < t.size() && t[i] == ']') {
          ++i;
        } else {
          for (;;) {
            Json item;
            if (!value(item)) return false;
            v.a.push_back(std::move(item));
            ws();
            if (i < t.size() && t[i] == ',') { ++i; continue; }
            if (i < t.size() && t[i] == ']') { ++i; break; }
            return fail("expected ',' or ']'");
          }
        }
      } else if (c == '"') {
        v.kind = Json::Kind::string;
        ok = str(v.s);
      } else if (c == '-' || (c >= '0' && c <= '9')) {
        v.kind = Json::Kind::number;
        bool neg = c == '-';
        if (neg) ++i;
        if (i >= t.size() || t[i] < '0' || t[i] > '9') return fail("bad number");
        long long n = 0;
        while (i < t.size() && t[i] >= '0' && t[i] <= '9') {
          if (n > 100000000000000000LL) return fail("number too large");
          n = n * 10 + (t[i++] - '0');
        }
        if (i < t.size() && (t[i] == '.' || t[i] == 'e' || t[i] == 'E')) return fail("only integers");
        v.n = neg ? -n : n;
      } else if (t.substr(i, 4) == "true") {
        v.kind = Json::Kind::boolean;
        v.b = true;
        i += 4;
      } else if (t.substr(i, 5) == "false") {
        v.kind = Json::Kind::boolean;
        i += 5;
      } else if (t.substr(i, 4) == "null") {
        i += 4;
      } else {
        return fail("unexpected character");
      }
      --depth;
      return ok;
    }
  };
  (void)ws;
  (void)fail;
  P p{text, i, err};
  if (!p.value(out)) return false;
  p.ws();
  if (i != text.size()) return p.fail("trailing characters");
  return true;
}

/// The loop both drivers run (docs/driver.md): one NDJSON input line from stdin (blank lines
/// skipped; a last line without a newline counts), one output line from @p handle to stdout, flushed
/// after each, and the trace file flushed with it. @p seq counts the inputs (the "in" field of the
/// outputs). Reads with read(2) (no iostreams: the EV3 binary carries none). Returns 0 at the end of
/// input, 1 when stdin cannot be read.
template <typename Handle>
int run_driver_lines(std::FILE* trace, unsigned long long& seq, Handle&& handle) {
  std::string buf;
  char chunk[4096];
  for (bool eof = false; !eof;) {
    const ssize_t n = ::read(0, chunk, sizeof chunk);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      std::fprintf(stderr, "driver: cannot read stdin: %s\n", std::strerror(errno));
      return 1;
    }
    if (n == 0) {
      eof = true;
      if (!buf.empty()) buf += '\n';
    } else {
      buf.append(chunk, static_cast<std::size_t>(n));
    }
    std::size_t start = 0;
    for (std::size_t nl; (nl = buf.find('\n', start)) != std::string::npos; start = nl + 1) {
      if (nl == start) continue;
      ++seq;
      const std::string out = handle(buf.substr(start, nl - start));
      std::fwrite(out.data(), 1, out.size(), stdout);
      std::fputc('\n', stdout);
      std::fflush(stdout);
      if (trace != nullptr) std::fflush(trace);
    }
    buf.erase(0, start);
  }
  return 0;
}

/// Where an "advance" input moves the clock: `now + ms`, or `to`. False, with @p err, if the input has
/// neither.
inline bool advance_target(const Json& in, std::uint64_t now, std::uint64_t& to, std::string& err) {
  if (in.has("ms")) to = now + static_cast<std::uint64_t>(in["ms"].num());
  else if (in.has("to")) to = static_cast<std::uint64_t>(in["to"].num());
  else {
    err = "advance needs \"ms\" or \"to\"";
    return false;
  }
  return true;
}

/// The output line for input @p seq that could not be handled; also logged on stderr as
/// "@p program: input N: @p msg".
inline std::string driver_error(const char* program, unsigned long long seq, const std::string& msg) {
  std::fprintf(stderr, "%s: input %llu: %s\n", program, seq, msg.c_str());
  std::string s = "{\"in\":" + std::to_string(seq) + ",\"error\":";
  ev3proto::json_string(s, msg);
  return s + "}";
}

/// The start of output line @p seq: `{"in":SEQ,"ok":TAKEN` (docs/driver.md "Outputs").
inline std::string output_start(unsigned long long seq, bool taken) {
  return "{\"in\":" + std::to_string(seq) + ",\"ok\":" + (taken ? "true" : "false");
}

/// The same with the core's clock @p now and the spec @p actions recorded for this input (JSON
/// objects; cleared here): `{"in":SEQ,"ok":TAKEN,"now":NOW,"actions":[...]`.
inline std::string output_start(unsigned long long seq, bool taken, std::uint64_t now,
                                std::vector<std::string>& actions) {
  std::string s = output_start(seq, taken) + ",\"now\":" + std::to_string(now) + ",\"actions\":[";
  for (std::size_t i = 0; i < actions.size(); ++i) {
    if (i) s += ',';
    s += actions[i];
  }
  actions.clear();
  return s + "]";
}

/// Lower-case hex of @p s.
inline std::string hex(std::string_view s) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string h;
  for (char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    h += kHex[c >> 4];
    h += kHex[c & 0xF];
  }
  return h;
}

/// Bytes of hex text @p h; false when it is not hex.
inline bool unhex(std::string_view h, std::string& out) {
  if (h.size() % 2 != 0) return false;
  auto nib = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  for (std::size_t i = 0; i < h.size(); i += 2) {
    const int a = nib(h[i]), b = nib(h[i + 1]);
    if (a < 0 || b < 0) return false;
    out += static_cast<char>(a * 16 + b);
  }
  return true;
}

/// The datagram of an input: "hex" (exact bytes) or "text" (the JSON string's bytes).
inline bool datagram_of(const Json& in, std::string& out, std::string& err) {
  if (in["hex"].kind == Json::Kind::string) {
    if (!unhex(in["hex"].s, out)) {
      err = "\"hex\" is not hex";
      return false;
    }
    return true;
  }
  if (in["text"].kind == Json::Kind::string) {
    out = in["text"].s;
    return true;
  }
  err = "a datagram needs \"text\" or \"hex\"";
  return false;
}

/// The inputs both drivers take alike (docs/driver.md), for a driver @p d that offers: error(msg),
/// output(taken), clear_actions(), configure(in, err), has_core(), core_now(), core_advance(to),
/// core_recv(bytes, in, now), early(type, in, reply) (its inputs that need no core: true when it took
/// one, its answer in @p reply) and own(type, in, now) (its other inputs). Parses @p line (one JSON
/// object); "config" configures; any other input first gets a core configured with defaults if
/// there is none; "advance" and "recv" go to the core.
template <typename D>
std::string dispatch_input(D& d, const std::string& line) {
  Json in;
  std::string err;
  if (!parse_json(line, in, err)) return d.error("not JSON: " + err);
  if (in.kind != Json::Kind::object) return d.error("an input is a JSON object");
  const std::string type = in["type"].str();
  d.clear_actions();
  if (type == "config") return d.configure(in, err) ? d.output(true) : d.error(err);
  std::string reply;
  if (d.early(type, in, reply)) return reply;
  if (!d.has_core()) {
    Json dflt;
    dflt.kind = Json::Kind::object;
    if (!d.configure(dflt, err)) return d.error(err);
  }
  const std::uint64_t now = d.core_now();
  if (type == "advance") {
    std::uint64_t to = now;
    if (!advance_target(in, now, to, err)) return d.error(err);
    d.core_advance(to);
    return d.output(true);
  }
  if (type == "recv") {
    std::string bytes;
    if (!datagram_of(in, bytes, err)) return d.error(err);
    d.core_recv(bytes, in, now);
    return d.output(true);
  }
  return d.own(type, in, now);
}

/// Reads the arguments of `PROGRAM --driver [--trace FILE]` (docs/driver.md) for @p program
/// ("ev3-agent"), whose @p core ("agent") takes the NDJSON @p inputs ("config, recv, ...") named in
/// the --help text. Opens the trace file into @p trace (nullptr without --trace). Returns -1 when
/// the driver is to run, else the exit status (0 after --help, 2 after an error, said on stderr).
inline int driver_options(int argc, char** argv, const char* program, const char* core, const char* inputs,
                          std::FILE*& trace) {
  trace = nullptr;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--driver") continue;
    if (a == "--help" || a == "-h") {
      std::printf(
          "usage: %s --driver [--trace FILE]\n\n"
          "The %s core on a virtual clock without sockets: one NDJSON input per stdin line\n"
          "(%s), one NDJSON output line per input\n"
          "on stdout, logs on stderr. docs/driver.md has the protocol.\n",
          program, core, inputs);
      if (trace != nullptr) std::fclose(trace);
      return 0;
    }
    if (a == "--trace" || a.rfind("--trace=", 0) == 0) {
      const std::string f = a == "--trace" ? (i + 1 < argc ? argv[++i] : "") : a.substr(8);
      if (trace != nullptr) std::fclose(trace);  // the last --trace counts
      trace = f.empty() ? nullptr : std::fopen(f.c_str(), "w");
      if (trace == nullptr) {
        std::fprintf(stderr, "%s: bad value for --trace: cannot open '%s'\n", program, f.c_str());
        return 2;
      }
      continue;
    }
    std::fprintf(stderr, "%s: --driver takes only --trace FILE (got '%s')\n", program, a.c_str());
    if (trace != nullptr) std::fclose(trace);
    return 2;
  }
  return -1;
}

}  // namespace ev3prog
