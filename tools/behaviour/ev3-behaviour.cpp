// ev3-behaviour: the behaviour language's tools (docs/behaviours.md): check a definition as the
// agent will on receipt, draw its automaton for Graphviz, write its compact one-line form, list and
// show the built-ins. See kUsage for the exact interface. Only I/O here: the library decides.
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <iterator>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "ev3proto/behaviour/builtins.hpp"
#include "ev3proto/behaviour/checker.hpp"
#include "ev3proto/behaviour/dot.hpp"
#include "ev3proto/behaviour/parser.hpp"
#include "ev3proto/behaviour/print.hpp"
#include "ev3proto/behaviour/request.hpp"
#include "ev3proto/wire.hpp"

namespace {

using namespace ev3proto::behaviour;

constexpr const char* kUsage =
    "usage: ev3-behaviour check [--model A] [--without DEVICE]... [--set KEY=VALUE]... FILE...\n"
    "       ev3-behaviour dot FILE\n"
    "       ev3-behaviour compact FILE\n"
    "       ev3-behaviour list\n"
    "       ev3-behaviour show NAME\n"
    "\n"
    "check    parse and check each FILE as a robot checks a BEHAVIOUR custom definition on receipt;\n"
    "         prints 'FILE: ok: ...' with its size on the wire, or each problem as\n"
    "         'FILE: line L col C: message' (on stderr). --without DEVICE: the robot lacks it\n"
    "         (left, right, ultrasonic, touch, colour, gyro: robot/'s roles); --set KEY=VALUE: a BEHAVIOUR\n"
    "         argument over the params (as 'behaviour ID NAME KEY=VALUE' sends it).\n"
    "dot      the automaton in Graphviz's language on stdout (dot -Tsvg draws it).\n"
    "compact  the definition on one line, without comments (the form to send: ';' costs one byte on\n"
    "         the wire, a new line three).\n"
    "list     the built-in behaviours' names; show NAME prints one's text (exit 2 if there is none).\n"
    "FILE - is stdin. Exit status: 0 ok, 1 a definition refused, 2 a bad command line or unreadable file.\n";

int usage_error(const std::string& msg) {
  std::cerr << "ev3-behaviour: " << msg << " (ev3-behaviour --help)\n";
  return 2;
}

bool read_file(const std::string& path, std::string& out) {
  if (path == "-") {
    out.assign(std::istreambuf_iterator<char>(std::cin), std::istreambuf_iterator<char>());
    return true;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  std::ostringstream s;
  s << in.rdbuf();
  out = s.str();
  return true;
}

std::string text_of(const Diagnostic& d) {
  char buf[kMaxMessage + 40];
  Text t(buf, sizeof buf);
  write(t, d);
  return std::string(t.view());
}

// The size of a BEHAVIOUR custom datagram carrying @p text (0: too big).
std::size_t datagram_size(std::string_view text) {
  static char buf[ev3proto::kMaxDatagram];
  return custom_datagram_size(text, buf);
}

bool device_named(std::string_view n, Role& d) {
  for (std::uint8_t k = 0; k < ev3proto::robot::kAllRoleCount; ++k)
    if (to_string(static_cast<Role>(k)) == n) {
      d = static_cast<Role>(k);
      return true;
    }
  return false;
}

// Parses @p path into @p def, printing the error; 0 ok, 1 refused, 2 unreadable.
int load(const std::string& path, std::string& text, Definition& def) {
  if (!read_file(path, text)) {
    std::cerr << "ev3-behaviour: cannot read " << path << "\n";
    return 2;
  }
  Diagnostic d;
  if (!parse(text, def, d)) {
    std::cerr << path << ": " << text_of(d) << "\n";
    return 1;
  }
  return 0;
}

int cmd_check(const std::vector<std::string>& args) {
  std::uint32_t robot = kModelA.devices;
  std::vector<std::string> sets, files;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--model" || a == "--without" || a == "--set") {
      if (i + 1 == args.size()) return usage_error(a + " needs a value");
      const std::string v = args[++i];
      if (a == "--model" && v != "A") return usage_error("unknown model '" + v + "' (known: A)");
      if (a == "--without") {
        Role d;
        if (!device_named(v, d)) return usage_error("unknown device '" + v + "'");
        robot &= ~role_bit(d);
      }
      if (a == "--set") sets.push_back(v);
    } else if (a.size() > 1 && a[0] == '-' && a != "-") {
      return usage_error("unknown option '" + a + "'");
    } else {
      files.push_back(a);
    }
  }
  if (files.empty()) return usage_error("check needs a FILE");
  std::vector<std::string_view> set_views(sets.begin(), sets.end());
  int status = 0;
  for (const std::string& path : files) {
    std::string text;
    static Definition def;
    const int rc = load(path, text, def);
    if (rc != 0) {
      status = std::max(status, rc);
      continue;
    }
    Diagnostic d;
    if (!apply_args(def, set_views.data(), set_views.size(), d)) {
      std::cerr << path << ": " << text_of(d) << "\n";
      status = std::max(status, 1);
      continue;
    }
    Findings f;
    if (!check(def, kModelA, robot, f)) {
      for (std::uint8_t k = 0; k < f.count; ++k) std::cerr << path << ": " << text_of(f.items[k]) << "\n";
      if (f.more) std::cerr << path << ": (more problems not shown)\n";
      status = std::max(status, 1);
      continue;
    }
    static char buf[kMaxSource * 2];
    Text c(buf, sizeof buf);
    compact(c, def);
    std::cout << path << ": ok: behaviour " << def.name.view() << ", " << int{def.state_count}
              << " states (end included), " << int{def.param_count} << (def.param_count == 1 ? " param" : " params")
              << "; BEHAVIOUR custom datagram "
              << datagram_size(text) << " bytes as written, " << datagram_size(c.view())
              << " compact (at most " << ev3proto::kMaxDatagram << ")\n";
  }
  return status;
}

int cmd_dot_or_compact(const std::string& cmd, const std::vector<std::string>& args) {
  if (args.size() != 1) return usage_error(cmd + " takes one FILE");
  std::string text;
  static Definition def;
  const int rc = load(args[0], text, def);
  if (rc != 0) return rc;
  static char buf[1 << 16];
  Text out(buf, sizeof buf);
  if (cmd == "dot") to_dot(out, def);
  else compact(out, def);
  std::cout << out.view();
  if (cmd == "compact") std::cout << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty()) return usage_error("missing command");
  const std::string cmd = args[0];
  args.erase(args.begin());
  if (cmd == "--help" || cmd == "-h" || cmd == "help") {
    std::cout << kUsage;
    return 0;
  }
  if (cmd == "check") return cmd_check(args);
  if (cmd == "dot" || cmd == "compact") return cmd_dot_or_compact(cmd, args);
  if (cmd == "list") {
    if (!args.empty()) return usage_error("list takes no arguments");
    for (const Builtin& b : kBuiltins) std::cout << b.name << "\n";
    return 0;
  }
  if (cmd == "show") {
    if (args.size() != 1) return usage_error("show takes one NAME");
    const Builtin* b = find_builtin(args[0]);
    if (b == nullptr) {
      std::cerr << "ev3-behaviour: no built-in behaviour '" << args[0] << "' (ev3-behaviour list)\n";
      return 2;
    }
    std::cout << b->text;
    return 0;
  }
  return usage_error("unknown command '" + cmd + "'");
}
