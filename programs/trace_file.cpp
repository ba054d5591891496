#include "ev3prog/trace_file.hpp"

#include <cerrno>
#include <cstring>

namespace ev3prog {

namespace {
constexpr ev3proto::Millis kFlushEveryMs = 200;
constexpr ev3proto::Millis kNever = ~ev3proto::Millis{0};
}  // namespace

std::string TraceFile::open(const std::string& path) {
  close();
  f_ = std::fopen(path.c_str(), "w");
  if (f_ == nullptr) return "cannot open '" + path + "': " + std::strerror(errno);
  next_flush_ = 0;
  return {};
}

void TraceFile::write(const std::string& line) {
  if (f_ == nullptr) return;
  std::fwrite(line.data(), 1, line.size(), f_);
  std::fputc('\n', f_);
}

void TraceFile::flush() {
  if (f_ != nullptr) std::fflush(f_);
}

ev3proto::Millis TraceFile::tick(ev3proto::Millis now) {
  if (f_ == nullptr) return kNever;
  if (now >= next_flush_) {
    flush();
    next_flush_ = now + kFlushEveryMs;
  }
  return next_flush_;
}

void TraceFile::close() {
  if (f_ == nullptr) return;
  std::fclose(f_);
  f_ = nullptr;
}

}  // namespace ev3prog
