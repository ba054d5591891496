// libFuzzer target: the receiver's check of signed datagrams (ev3proto/auth.hpp) against a plain
// model of docs/protocol.md "Signed datagrams". The input is a program of steps: sign a datagram
// with the fleet key and any counter, take bytes as they are, flip a bit of the last signed one,
// send it again. Each result goes to one Verifier (4 senders); the model says which must be taken:
// only genuine tags (the fuzzer has no key), each counter once, none older than the window or of an
// older boot, no fifth sender. Anything else traps. Also linked with replay_main.cpp (the corpus).
#include <cstddef>
#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <string_view>

#include "ev3proto/auth.hpp"
#include "fuzz_input.hpp"

namespace auth = ev3proto::auth;

namespace {

using fuzzin::Reader;
using fuzzin::violation;

struct SenderModel {
  std::uint64_t boot = 0;
  std::uint64_t top = 0;
  std::set<std::uint64_t> seqs;
};

/// The model: per sender id, the newest boot and the seqs taken in it.
struct Model {
  std::map<std::uint32_t, SenderModel> senders;
  bool takes(std::uint32_t id, std::uint64_t counter) const {
    const std::uint64_t boot = counter >> auth::kSeqBits, seq = counter & auth::kSeqMask;
    const auto it = senders.find(id);
    if (it == senders.end()) return senders.size() < 4;
    const SenderModel& s = it->second;
    if (boot != s.boot) return boot > s.boot;
    if (seq > s.top) return true;
    return s.top - seq < auth::kWindow && s.seqs.count(seq) == 0;
  }
  void take(std::uint32_t id, std::uint64_t counter) {
    const std::uint64_t boot = counter >> auth::kSeqBits, seq = counter & auth::kSeqMask;
    SenderModel& s = senders[id];
    if (s.seqs.empty() || boot > s.boot) {
      s = SenderModel{boot, seq, {seq}};
      return;
    }
    s.seqs.insert(seq);
    if (seq > s.top) s.top = seq;
  }
};

/// The sender field as docs/protocol.md defines a number: canonical decimal 0..65535, then ':'.
bool sender_of(std::string_view d, std::uint32_t& id) {
  const std::size_t colon = d.find(':');
  if (colon == std::string_view::npos || colon == 0 || colon > 5 || (colon > 1 && d[0] == '0')) return false;
  id = 0;
  for (std::size_t i = 0; i < colon; ++i) {
    if (d[i] < '0' || d[i] > '9') return false;
    id = id * 10 + static_cast<std::uint32_t>(d[i] - '0');
  }
  return id <= 65535;
}

/// Genuine: a well-formed trailer of our key whose tag matches; then its sender and counter.
bool genuine(const auth::Key& key, std::string_view b, std::uint32_t& id, std::uint64_t& counter) {
  if (b.size() < auth::kTrailer || b[b.size() - auth::kTrailer] != '\n') return false;
  const std::string_view t = b.substr(b.size() - auth::kTrailer + 1);
  if (t.substr(0, auth::kIdHex) != key.id()) return false;
  counter = 0;
  for (std::size_t i = 0; i < auth::kCounterHex; ++i) {
    const int v = auth::detail::hex_value(t[auth::kIdHex + i]);
    if (v < 0) return false;
    counter = counter * 16 + static_cast<std::uint64_t>(v);
  }
  unsigned char want[auth::kTagBytes];
  key.tag(b.substr(0, b.size() - 2 * auth::kTagBytes), want);
  std::string hex(2 * auth::kTagBytes, '0');
  auth::detail::to_hex(want, auth::kTagBytes, hex.data());
  return t.substr(auth::kIdHex + auth::kCounterHex) == hex && sender_of(b, id);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static auth::Key key = [] {
    auth::Key k;
    if (sodium_init() < 0 || auth::Key::parse(std::string(64, 'C'), k) != nullptr) violation();
    return k;
  }();
  static auth::Verifier<4>* v = nullptr;  // one per input, off the stack (4 senders, 8 slots)
  delete v;
  v = new auth::Verifier<4>(key);
  Model model;
  Reader in{data, size};
  std::string last;
  while (in.n > 0) {
    std::string bytes;
    switch (in.byte() % 4) {
      case 0: {  // sign "S:1:M:5:IDLE" with any boot and seq
        const std::string d = std::to_string(in.byte() % 6) + ":1:" + std::to_string(in.byte()) + ":5:IDLE";
        auth::Signer s(key, 1 + in.byte() % 3, in.u16() % 300);
        char t[auth::kTrailer];
        s.seal(d, t);
        bytes = last = d + std::string(t, auth::kTrailer);
        break;
      }
      case 1: {  // bytes as they are
        const std::size_t len = in.u16() % 200;
        for (std::size_t i = 0; i < len && in.n > 0; ++i) bytes.push_back(static_cast<char>(in.byte()));
        break;
      }
      case 2:  // the last signed one with a bit flipped
        bytes = last;
        if (!bytes.empty()) bytes[in.u16() % bytes.size()] ^= static_cast<char>(1 << (in.byte() % 8));
        break;
      default:  // the last signed one again
        bytes = last;
        break;
    }
    std::uint32_t id = 0;
    std::uint64_t counter = 0;
    const bool expect = genuine(key, bytes, id, counter) && model.takes(id, counter);
    std::string_view out;
    const auth::Verdict r = v->open(bytes, out);
    if ((r == auth::Verdict::ok) != expect) violation();
    if (expect) {
      if (out != std::string_view(bytes).substr(0, bytes.size() - auth::kTrailer)) violation();
      model.take(id, counter);
    }
    if (v->senders() != model.senders.size()) violation();
  }
  return 0;
}
