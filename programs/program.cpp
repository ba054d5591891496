#include "ev3prog/program.hpp"

#include <cerrno>

#include "ev3io/state_file.hpp"

namespace ev3prog {

bool save_state_file(const char* program, const char* what, const std::string& path, std::string_view text,
                     ev3io::Logger& log) {
  std::string err;
  if (ev3io::write_state_file(path, text, err)) return true;
  log.log(ev3io::kError, "%s; %s is not on disk: sending nothing more, exiting", err.c_str(), what);
  std::fprintf(stderr, "%s: %s; %s is not on disk: sending nothing more, exiting\n", program, err.c_str(), what);
  return false;
}

bool open_outputs(const char* program, const char* log_name, const ev3io::CommonOptions& o, ev3io::Logger& log,
                  TraceFile& trace) {
  log.set_name(log_name);
  log.set_level(o.log_level);
  if (!o.log_file.empty() && !log.open(o.log_file)) {
    std::fprintf(stderr, "%s: bad value for --log-file: cannot open '%s': %s\n", program, o.log_file.c_str(),
                 std::strerror(errno));
    return false;
  }
  if (o.trace_file.empty()) return true;
  const std::string err = trace.open(o.trace_file);
  if (!err.empty()) std::fprintf(stderr, "%s: bad value for --trace: %s\n", program, err.c_str());
  return err.empty();
}

bool load_script(const char* program, const char* flag, const std::string& path, Script& script) {
  if (path.empty()) return true;
  const std::string err = script.load(path);
  if (!err.empty()) std::fprintf(stderr, "%s: bad value for %s: %s\n", program, flag, err.c_str());
  return err.empty();
}

std::string agent_address(const std::map<std::uint16_t, ev3proto::RegistryEntry>& reg, std::uint16_t agent,
                          const ev3io::UdpTransport& net) {
  const auto it = reg.find(agent);
  if (it == reg.end()) return {};
  const ev3io::Endpoint* ep = net.endpoint_of(it->second.peer);
  return ep != nullptr ? ep->str() : std::string();
}

}  // namespace ev3prog
