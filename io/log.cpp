#include "ev3io/log.hpp"

#include <cstdarg>

#include "ev3io/loop.hpp"

namespace ev3io {

Logger::~Logger() {
  flush();
  if (file_ != nullptr) std::fclose(file_);
}

bool Logger::open(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "a");
  if (f == nullptr) return false;
  if (file_ != nullptr) std::fclose(file_);
  file_ = f;
  return true;
}

void Logger::log(int level, const char* fmt, ...) {
  if (!enabled(level)) return;
  const Millis now = monotonic_ms();
  if (start_ == 0) start_ = now, last_flush_ = now;
  static constexpr char kTag[] = "-EIDV";
  char head[64];
  const Millis t = now - start_;
  std::snprintf(head, sizeof head, "[%6llu.%03llu] %c %s: ", static_cast<unsigned long long>(t / 1000),
                static_cast<unsigned long long>(t % 1000), kTag[level], name_.c_str());
  buf_ += head;
  char text[1024];
  va_list ap;
  va_start(ap, fmt);
  const int n = std::vsnprintf(text, sizeof text, fmt, ap);
  va_end(ap);
  if (n > 0) buf_.append(text, static_cast<std::size_t>(n) < sizeof text ? static_cast<std::size_t>(n) : sizeof text - 1);
  buf_ += '\n';
  if (level == kError || buf_.size() > 8192) flush();
}

void Logger::flush() {
  if (buf_.empty()) return;
  std::FILE* f = file_ != nullptr ? file_ : stderr;
  std::fwrite(buf_.data(), 1, buf_.size(), f);
  std::fflush(f);
  buf_.clear();
}

Millis Logger::tick(Millis now) {
  if (buf_.empty()) return kNever;
  if (now >= last_flush_ + kFlushMs) {
    flush();
    last_flush_ = now;
    return kNever;
  }
  return last_flush_ + kFlushMs;
}

}  // namespace ev3io
