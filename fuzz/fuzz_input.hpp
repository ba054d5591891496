// What the fuzz targets share: the input read as a program of steps (Reader), and datagrams made
// from it that are often valid (Datagrams: header fields and params from a small vocabulary, so the
// cores' handlers are reached, not only the decoder's refusals).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>

#include "ev3proto/wire.hpp"

namespace fuzzin {

/// A property failed: says which on stderr (the finding's log names it), then traps.
[[noreturn]] inline void violation(const char* what = "a property") {
  std::fprintf(stderr, "fuzz: violated: %s\n", what);
  __builtin_trap();
}

/// The fuzz input, consumed byte by byte (0 once it is used up).
struct Reader {
  const std::uint8_t* p;
  std::size_t n;
  std::uint8_t byte() {
    if (n == 0) return 0;
    --n;
    return *p++;
  }
  std::uint16_t u16() {
    const std::uint8_t lo = byte();
    return static_cast<std::uint16_t>(lo | (byte() << 8));
  }
  /// Up to @p max bytes as they are.
  std::string bytes(std::size_t max) {
    std::string s;
    const std::size_t len = byte() % (max + 1);
    for (std::size_t i = 0; i < len && n > 0; ++i) s.push_back(static_cast<char>(byte()));
    return s;
  }
};

/// A datagram "S:R:M:T:params" with each field picked by the input: the sender and receiver among
/// @p ids, a msgid near a moving base (repeats, stale and fresh ones), any type 1..42 (40-42: the
/// reliable reports', with their numbers and a report of the sender inside REPORT), 0..4 params
/// from the protocol's words.
inline std::string datagram(Reader& in, const std::uint16_t* ids, std::size_t n_ids, std::uint32_t& msgid_base) {
  static constexpr const char* kWords[] = {
      "IDLE", "ACTIVE", "WORKING", "PAUSED", "PANIC", "explore", "wait", "seconds=1", "seconds=0", "0", "1", "2",
      "3", "5", "7", "100", "50001", "65535", "4294967295", "A", "BATTERY_LOW", "in1", "COL-REFLECT", "42",
      "custom", "x=1", "", "missing device"};
  constexpr std::size_t kN = sizeof kWords / sizeof kWords[0];
  const std::uint8_t b = in.byte();
  if (b & 0x80) msgid_base += in.byte();
  const std::uint32_t msgid = msgid_base + (b & 7) - 3;
  const std::uint16_t sender = ids[in.byte() % n_ids];
  const std::uint16_t receiver = ids[in.byte() % n_ids];
  const unsigned type = 1 + in.byte() % 40;
  std::string d = std::to_string(sender) + ":" + std::to_string(receiver) + ":" + std::to_string(msgid) + ":";
  if (type == 40) {  // the reliable reports' types 40-42, numbers near the start, a report inside REPORT
    static constexpr const char* kNums[] = {"0", "1", "2", "3", "4", "5", "9", "4294967295"};
    const unsigned t = 40 + in.byte() % 3;
    d += std::to_string(t) + ":" + kNums[in.byte() % 8];
    if (t == 40) d += std::string(":") + kNums[in.byte() % 8] + ":" + std::to_string(sender) + "%3A1%3A" +
                      std::to_string(msgid) + "%3A" + (in.byte() & 1 ? "15%3A0" : "20%3AOBSTACLE_DETECTED%3Ain1");
    if (t == 41) d += std::string(":") + kNums[in.byte() % 8];
    return d;
  }
  d += std::to_string(type);
  for (int i = in.byte() % 5; i > 0; --i) d += std::string(":") + kWords[in.byte() % kN];
  return d;
}

/// The steps a core target shares, of the eight a step byte picks: 0-3 a datagram from the
/// vocabulary, 4 raw bytes, each from peer 1..4 to @p core at @p now; 5 time passing (up to
/// @p max_gap ms; @p now moves). False for 6 and 7, the target's own steps.
template <typename Core, std::size_t N>
bool shared_step(std::uint8_t op, Reader& in, Core& core, const std::uint16_t (&ids)[N], std::uint32_t& base,
                 std::uint64_t& now, unsigned max_gap) {
  const std::uint32_t from = 1u + in.byte() % 4u;
  if (op <= 3) {
    core.handle_datagram(datagram(in, ids, N, base), from, now);
  } else if (op == 4) {
    core.handle_datagram(in.bytes(80), from, now);
  } else if (op == 5) {
    now += in.u16() % max_gap;
    core.advance(now);
  } else {
    return false;
  }
  return true;
}

/// Every datagram a core sends must be one the codec takes, spelled canonically.
inline void check_output(std::string_view bytes) {
  static ev3proto::Message m;
  if (!ev3proto::decode(bytes, m).ok()) violation("an output that does not decode");
  static char out[ev3proto::kMaxDatagram];
  const ev3proto::EncodeResult e = ev3proto::encode(m, out, sizeof out);
  if (!e.ok() || std::string_view(out, e.size) != bytes) violation("an output not spelled canonically");
}

}  // namespace fuzzin
