// libFuzzer target: decode any bytes; an accepted datagram must be canonical (encode gives the same
// bytes) and decode(encode(m)) must give m back; a rejection must carry a valid reason and field.
// Any violation traps. Also linked with replay_main.cpp to run the committed corpus under gcc/armel.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "ev3proto/wire.hpp"

namespace {

[[noreturn]] void violation() { __builtin_trap(); }

bool valid_rejection(ev3proto::DecodeResult r) {
  using ev3proto::Reason;
  switch (r.reason) {
    case Reason::empty:
    case Reason::too_long: return r.field == 0;
    case Reason::too_few_fields:
    case Reason::bad_number:
    case Reason::out_of_range:
    case Reason::unknown_type:
    case Reason::bad_escape:
    case Reason::non_printable_byte:
    case Reason::too_many_params: return r.field <= ev3proto::kFieldParam0 + ev3proto::kMaxParams;
    case Reason::ok: return false;
  }
  return false;
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  static ev3proto::Message first;   // static: 4 KiB each, keep them off the fuzzer's stack
  static ev3proto::Message second;
  static char out[ev3proto::kMaxDatagram];

  const ev3proto::DecodeResult r = ev3proto::decode(input, first);
  if (!r.ok()) {
    if (!valid_rejection(r) || ev3proto::to_string(r.reason).empty()) violation();
    return 0;
  }
  if (size > ev3proto::kMaxDatagram || first.param_count() > ev3proto::kMaxParams) violation();
  const ev3proto::EncodeResult e = ev3proto::encode(first, out, sizeof out);
  if (!e.ok() || e.size != size || std::memcmp(out, data, size) != 0) violation();
  // Encoding into a buffer one byte too small must refuse as too long.
  if (ev3proto::encode(first, out, size - 1).reason != ev3proto::Reason::too_long) violation();
  const ev3proto::DecodeResult r2 = ev3proto::decode(std::string_view(out, e.size), second);
  if (!r2.ok()) violation();
  if (second.sender != first.sender || second.receiver != first.receiver || second.msgid != first.msgid ||
      second.type != first.type || second.param_count() != first.param_count())
    violation();
  for (std::size_t i = 0; i < first.param_count(); ++i)
    if (second.param(i) != first.param(i)) violation();
  if (!(second == first)) violation();
  return 0;
}
