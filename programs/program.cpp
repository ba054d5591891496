#include "ev3prog/program.hpp"

#include <algorithm>
#include <cassert>
#include <cerrno>

#include <ctime>

#include "ev3io/key_file.hpp"
#include "ev3io/state_file.hpp"

namespace ev3prog {

int Shell::open_signing(const std::string& path) {
  key_ = std::make_unique<ev3proto::auth::Key>();
  const std::string err = ev3io::load_key_file(path, *key_);
  if (!err.empty()) {
    std::fprintf(stderr, "%s: bad value for --key-file: %s\n", program_, err.c_str());
    return 2;
  }
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  const auto now_ms = static_cast<std::uint64_t>(ts.tv_sec) * 1000u + static_cast<std::uint64_t>(ts.tv_nsec) / 1000000u;
  signer_ = std::make_unique<ev3proto::auth::Signer>(*key_, ev3proto::auth::choose_boot(now_ms));
  opener_ = std::make_unique<ev3proto::auth::Verifier<65536>>(*key_);
  net.sign_with(signer_.get());
  log.log(ev3io::kInfo, "signed mode: key id %.*s, boot %llu", static_cast<int>(key_->id().size()),
          key_->id().data(), static_cast<unsigned long long>(signer_->boot()));
  return 0;
}

bool Shell::authentic() {
  std::string_view d;
  const ev3proto::auth::Verdict v = opener_->open(bytes_, d);
  if (v == ev3proto::auth::Verdict::ok) {
    bytes_.resize(d.size());
    return true;
  }
  drop(std::string("auth:") + ev3proto::auth::verdict_name(v), bytes_, &from_);
  return false;
}

int Shell::open(const char* log_name, const ev3io::CommonOptions& o) {
  log.set_name(log_name);
  log.set_level(o.log_level);
  if (!o.log_file.empty() && !log.open(o.log_file)) {
    std::fprintf(stderr, "%s: bad value for --log-file: cannot open '%s': %s\n", program_, o.log_file.c_str(),
                 std::strerror(errno));
    return 2;
  }
  if (!o.trace_file.empty()) {
    const std::string err = trace_file.open(o.trace_file);
    if (!err.empty()) {
      std::fprintf(stderr, "%s: bad value for --trace: %s\n", program_, err.c_str());
      return 2;
    }
  }
  if (!o.key_file.empty()) {
    const int rc = open_signing(o.key_file);
    if (rc != 0) return rc;
  }
  std::string err;
  if (!net.open(o.bind_addr, o.port, err)) {
    log.log(ev3io::kError, "%s", err.c_str());
    log.flush();
    std::fprintf(stderr, "%s: %s\n", program_, err.c_str());
    return 1;
  }
  return 0;
}

bool Shell::load_script(const char* flag, const std::string& path) {
  if (path.empty()) return true;
  const std::string err = script.load(path);
  if (!err.empty()) std::fprintf(stderr, "%s: bad value for %s: %s\n", program_, flag, err.c_str());
  return err.empty();
}

bool Shell::read_state(const char* flag, const std::string& path, std::optional<std::string>& text) {
  std::string got, err;
  text.reset();
  if (ev3io::read_state_file(path, got, err)) {
    text = std::move(got);
    return true;
  }
  if (err.empty()) return true;  // no file: a first start
  std::fprintf(stderr, "%s: bad value for %s: %s\n", program_, flag, err.c_str());
  return false;
}

bool Shell::damaged(const char* flag, const std::string& path, std::string_view why) {
  std::fprintf(stderr, "%s: bad value for %s: %s is damaged: %.*s\n", program_, flag, path.c_str(),
               static_cast<int>(why.size()), why.data());
  return false;
}

bool Shell::save_state(const char* what, const std::string& path, std::string_view text) {
  std::string err;
  // The trace's records of the change reach the file with it, before any datagram announces it.
  trace_file.flush();
  if (path.empty() || ev3io::write_state_file(path, text, err)) return true;
  log.log(ev3io::kError, "%s; %s is not on disk: sending nothing more, exiting", err.c_str(), what);
  std::fprintf(stderr, "%s: %s; %s is not on disk: sending nothing more, exiting\n", program_, err.c_str(), what);
  return false;
}

void Shell::drop(const std::string& why, std::string_view bytes, const ev3io::Endpoint* from) {
  const std::uint64_t n = ++drops[why];
  if (log.enabled(ev3io::kVerbose))
    log.log(ev3io::kVerbose, "drop (%s, %llu so far)%s%s: %s", why.c_str(), static_cast<unsigned long long>(n),
            from == nullptr ? "" : " from ", from == nullptr ? "" : from->str().c_str(), printable(bytes).c_str());
}

std::string Shell::drops_line() const {
  std::string s;
  for (const auto& kv : drops) s += (s.empty() ? "" : " ") + kv.first + "=" + std::to_string(kv.second);
  return s.empty() ? "none" : s;
}

int Shell::wait(Millis now, Millis deadline, bool more, pollfd* extra, std::size_t n_extra) {
  deadline = std::min({deadline, net.next_send(), log.tick(now), trace_file.tick(now)});
  if (more) deadline = now;
  assert(n_extra <= kMaxExtra);
  pollfd p[kMaxExtra + 1] = {{net.fd(), POLLIN, 0}};
  n_extra = std::min(n_extra, kMaxExtra);
  for (std::size_t i = 0; i < n_extra; ++i) p[i + 1] = extra[i];
  const int n = signals.wait(p, n_extra + 1, deadline);
  for (std::size_t i = 0; i < n_extra; ++i) extra[i].revents = p[i + 1].revents;
  return n;
}

void Shell::log_stop(const char* why) {
  net.flush_all();
  if (state_failed)
    log.log(ev3io::kError, "stopping: the state file could not be written; drops: %s", drops_line().c_str());
  else if (why != nullptr)
    log.log(ev3io::kInfo, "stopping (%s); drops: %s", why, drops_line().c_str());
  else
    log.log(ev3io::kInfo, "stopping (signal %d); drops: %s", signals.stop_signal(), drops_line().c_str());
}

void Shell::close() {
  log.flush();
  trace_file.close();
}

std::string decode_drop_key(ev3proto::Reason r) {
  std::string k = "decode:" + std::string(ev3proto::to_string(r));
  std::replace(k.begin(), k.end(), ' ', '_');
  return k;
}

std::string printable(std::string_view d) {
  std::string s;
  for (std::size_t i = 0; i < d.size() && i < 100; ++i) {
    const auto c = static_cast<unsigned char>(d[i]);
    if (c >= 0x20 && c < 0x7F) {
      s += static_cast<char>(c);
    } else {
      char b[5];
      std::snprintf(b, sizeof b, "\\x%02X", c);
      s += b;
    }
  }
  if (d.size() > 100) s += "...";
  return s;
}

std::string agent_address(const std::map<std::uint16_t, ev3proto::RegistryEntry>& reg, std::uint16_t agent,
                          const ev3io::UdpTransport& net) {
  const auto it = reg.find(agent);
  if (it == reg.end()) return {};
  const ev3io::Endpoint* ep = net.endpoint_of(it->second.peer);
  return ep != nullptr ? ep->str() : std::string();
}

}  // namespace ev3prog
