#include "ev3io/fault.hpp"

namespace ev3io {

std::uint64_t FaultInjector::next() noexcept {
  std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

double FaultInjector::percent() noexcept {
  return static_cast<double>(next() >> 11) * (100.0 / 9007199254740992.0);  // 53 bits
}

Millis FaultInjector::one(Millis at) {
  Millis t = at + cfg_.delay_ms;
  if (cfg_.delay_ms > 0) ++stats_.delayed;
  if (cfg_.reorder > 0 && percent() < cfg_.reorder) {
    t += kReorderMinMs + next() % (kReorderSpreadMs + 1);
    ++stats_.reordered;
  }
  return t;
}

void FaultInjector::schedule(Millis at, std::vector<Millis>& out) {
  ++stats_.copies;
  if (!cfg_.enabled()) {
    out.push_back(at);
    return;
  }
  // Always draw the same number of values per decision, so one knob does not shift the others.
  const double loss = percent();
  const double dup = percent();
  if (loss < cfg_.loss) {
    ++stats_.lost;
    return;
  }
  out.push_back(one(at));
  if (dup < cfg_.dup) {
    ++stats_.duplicated;
    out.push_back(one(at + 1));
  }
}

}  // namespace ev3io
