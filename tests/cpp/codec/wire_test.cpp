// decode/encode of wire format v2 against docs/protocol.md: every rejection with its field, the
// canonical escapes, the boundaries, round trips and encode's refusals.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <string>
#include <type_traits>
#include <vector>

#include "ev3proto/wire.hpp"

namespace {

using namespace ev3proto;
using namespace std::string_literals;

struct Case {
  std::string datagram;
  Reason reason;
  unsigned field;
};

std::string show(const std::string& d) {
  std::string out;
  for (char ch : d) {
    const auto c = static_cast<unsigned char>(ch);
    if (c >= 0x20 && c < 0x7F && c != '\\') {
      out += ch;
    } else {
      char b[8];
      std::snprintf(b, sizeof b, "\\x%02X", c);
      out += b;
    }
  }
  return out.size() > 120 ? out.substr(0, 120) + "...(" + std::to_string(d.size()) + " bytes)" : out;
}

void expect_decode(const Case& c) {
  Message m;
  const DecodeResult r = decode(c.datagram, m);
  EXPECT_EQ(to_string(r.reason), to_string(c.reason)) << "datagram: " << show(c.datagram);
  EXPECT_EQ(unsigned{r.field}, c.field) << "datagram: " << show(c.datagram);
}

std::string params_of(std::size_t n, const std::string& value) {
  std::string s;
  for (std::size_t i = 0; i < n; ++i) s += ":" + value;
  return s;
}

TEST(Reason, NamesAreExactlyThoseOfTheProtocol) {
  EXPECT_EQ(to_string(Reason::empty), "empty");
  EXPECT_EQ(to_string(Reason::too_long), "too long");
  EXPECT_EQ(to_string(Reason::too_few_fields), "too few fields");
  EXPECT_EQ(to_string(Reason::bad_number), "bad number");
  EXPECT_EQ(to_string(Reason::out_of_range), "out of range");
  EXPECT_EQ(to_string(Reason::unknown_type), "unknown type");
  EXPECT_EQ(to_string(Reason::bad_escape), "bad escape");
  EXPECT_EQ(to_string(Reason::non_printable_byte), "non-printable byte");
  EXPECT_EQ(to_string(Reason::too_many_params), "too many params");
  EXPECT_EQ(to_string(Reason::ok), "ok");
}

TEST(Decode, WorkedExample) {
  Message m;
  const DecodeResult r = decode("7:1:12:5:WORKING", m);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(static_cast<bool>(r));
  EXPECT_EQ(m.sender, 7);
  EXPECT_EQ(m.receiver, 1);
  EXPECT_EQ(m.msgid, 12u);
  EXPECT_EQ(m.type, MsgType::PING);
  ASSERT_EQ(m.param_count(), 1u);
  EXPECT_EQ(m.param(0), "WORKING");
  EXPECT_EQ(m.param_state(0), AgentState::WORKING);
  EXPECT_EQ(m.param(1), "");
  char buf[64];
  const EncodeResult e = encode(m, buf, sizeof buf);
  ASSERT_TRUE(e.ok());
  EXPECT_EQ(std::string(buf, e.size), "7:1:12:5:WORKING");
}

TEST(Decode, EmptyAndTooLong) {
  const std::string head = "1:2:3:7:";
  expect_decode({"", Reason::empty, 0});
  expect_decode({head + std::string(4096 - head.size(), 'a'), Reason::ok, 0});
  expect_decode({head + std::string(4097 - head.size(), 'a'), Reason::too_long, 0});
  // Too long comes before everything else, even garbage or nothing valid at all.
  expect_decode({std::string(4097, '\x01'), Reason::too_long, 0});
  expect_decode({std::string(100000, ':'), Reason::too_long, 0});
  // 4096 bytes made mostly of escapes.
  std::string esc = head;
  while (esc.size() + 3 <= 4096) esc += "%3A";
  esc += std::string(4096 - esc.size(), 'x');
  ASSERT_EQ(esc.size(), 4096u);
  Message m;
  ASSERT_TRUE(decode(esc, m).ok());
  EXPECT_EQ(m.param(0).substr(0, 3), ":::");
}

TEST(Decode, HeaderFields) {
  const std::vector<Case> cases = {
      {"7", Reason::too_few_fields, 1},
      {"7:", Reason::bad_number, 1},
      {"7:1", Reason::too_few_fields, 2},
      {"7:1:", Reason::bad_number, 2},
      {"7:1:12", Reason::too_few_fields, 3},
      {"7:1:12:", Reason::bad_number, 3},
      {":", Reason::bad_number, 0},
      {":1:2:5:IDLE", Reason::bad_number, 0},
      {"x", Reason::bad_number, 0},
      {"x:1:2:5:IDLE", Reason::bad_number, 0},
      {"07:1:12:5:IDLE", Reason::bad_number, 0},
      {"00:1:12:5:IDLE", Reason::bad_number, 0},
      {"+7:1:12:5:IDLE", Reason::bad_number, 0},
      {"-7:1:12:5:IDLE", Reason::bad_number, 0},
      {" 7:1:12:5:IDLE", Reason::bad_number, 0},
      {"7 :1:12:5:IDLE", Reason::bad_number, 0},
      {"%37:1:12:5:IDLE", Reason::bad_number, 0},
      {"\x01:1:12:5:IDLE", Reason::bad_number, 0},
      {"\xff:1:12:5:IDLE", Reason::bad_number, 0},
      {"7:01:12:5:IDLE", Reason::bad_number, 1},
      {"7:1:012:5:IDLE", Reason::bad_number, 2},
      {"7:1:12:05:IDLE", Reason::bad_number, 3},
      {"7:1:1a:5:IDLE", Reason::bad_number, 2},
      {"7:1:12:5x:IDLE", Reason::bad_number, 3},
      {"0:0:0:5:IDLE", Reason::ok, 0},
      {"65535:65535:4294967295:5:IDLE", Reason::ok, 0},
      {"65536:1:12:5:IDLE", Reason::out_of_range, 0},
      {"7:65536:12:5:IDLE", Reason::out_of_range, 1},
      {"7:1:4294967296:5:IDLE", Reason::out_of_range, 2},
      {"7:1:9999999999:5:IDLE", Reason::out_of_range, 2},
      {"7:1:10000000000:5:IDLE", Reason::out_of_range, 2},
      {"7:1:99999999999999999999999999999999999:5:IDLE", Reason::out_of_range, 2},
      {"99999999999999999999999999999999999:1:2:5:IDLE", Reason::out_of_range, 0},
      {"18446744073709551616:1:2:5:IDLE", Reason::out_of_range, 0},
      {"99999999999999999999999x:1:2:5:IDLE", Reason::bad_number, 0},  // not canonical beats too big
      {"0999999999999999999999:1:2:5:IDLE", Reason::bad_number, 0},
      {"65536:x:2:5:IDLE", Reason::out_of_range, 0},  // the first problem wins
      {"7:1:12:0", Reason::out_of_range, 3},
      {"7:1:12:256", Reason::out_of_range, 3},
      {"7:1:12:99999999999", Reason::out_of_range, 3},
      {"7:1:12:34", Reason::unknown_type, 3},
      {"7:1:12:39", Reason::unknown_type, 3},
      {"7:1:12:255", Reason::unknown_type, 3},
      {"7:1:12:34:\x01", Reason::unknown_type, 3},
      {"7:1:12:5", Reason::too_few_fields, 4},
      {"7:1:12:8", Reason::ok, 0},
      {"7:1:12:8:", Reason::too_many_params, 4},
  };
  for (const Case& c : cases) expect_decode(c);
}

TEST(Decode, ParamBytesAndEscapes) {
  const std::vector<Case> cases = {
      {"1:2:3:7:", Reason::ok, 0},  // BEHAVIOUR with one empty param
      {"1:2:3:7::", Reason::ok, 0},
      {"1:2:3:7:a%3Ab", Reason::ok, 0},
      {"1:2:3:7:%25", Reason::ok, 0},
      {"1:2:3:7:%00%01%1F%7F%80%FF", Reason::ok, 0},
      {"1:2:3:7:%3a", Reason::bad_escape, 4},   // lower-case hex
      {"1:2:3:7:%41", Reason::bad_escape, 4},   // 'A' need not be escaped
      {"1:2:3:7:%20", Reason::bad_escape, 4},   // space need not be escaped
      {"1:2:3:7:%7E", Reason::bad_escape, 4},   // '~' need not be escaped
      {"1:2:3:7:%30", Reason::bad_escape, 4},
      {"1:2:3:7:%", Reason::bad_escape, 4},
      {"1:2:3:7:%3", Reason::bad_escape, 4},
      {"1:2:3:7:%:", Reason::bad_escape, 4},
      {"1:2:3:7:%3:A", Reason::bad_escape, 4},
      {"1:2:3:7:%G0", Reason::bad_escape, 4},
      {"1:2:3:7:%0g", Reason::bad_escape, 4},
      {"1:2:3:7:%%25", Reason::bad_escape, 4},
      {"1:2:3:7:%\x01", Reason::bad_escape, 4},    // left to right: the '%' comes first
      {"1:2:3:7:%41\x01", Reason::bad_escape, 4},
      {"1:2:3:7:\x01%41", Reason::non_printable_byte, 4},
      {"1:2:3:7:\x7f", Reason::non_printable_byte, 4},
      {"1:2:3:7:\x80", Reason::non_printable_byte, 4},
      {"1:2:3:7:\xff", Reason::non_printable_byte, 4},
      {"1:2:3:7:\t", Reason::non_printable_byte, 4},
      {"1:2:3:7:"s + '\0', Reason::non_printable_byte, 4},
      {"1:2:3:7:abcdefghijklmnopqrstuvw\x1f", Reason::non_printable_byte, 4},
      {"1:2:3:7:ok:ok:\x01", Reason::non_printable_byte, 6},
      {"1:2:3:7:ok:ok:abcdefghijklmnop%4", Reason::bad_escape, 6},
      {"1:2:3:7: !\"#$&'()*+,-./09;<=>?@AZ[\\]^_`az{|}~", Reason::ok, 0},
  };
  for (const Case& c : cases) expect_decode(c);

  Message m;
  ASSERT_TRUE(decode("1:2:3:7:a%3Ab:%25%00%FF:", m).ok());
  ASSERT_EQ(m.param_count(), 3u);
  EXPECT_EQ(m.param(0), "a:b");
  EXPECT_EQ(m.param(1), "%\0\xff"s);
  EXPECT_EQ(m.param(2), "");
}

TEST(Decode, TypedParams) {
  const std::vector<Case> cases = {
      // PING: state
      {"1:2:3:5:IDLE", Reason::ok, 0},
      {"1:2:3:5:ACTIVE", Reason::ok, 0},
      {"1:2:3:5:WORKING", Reason::ok, 0},
      {"1:2:3:5:PAUSED", Reason::ok, 0},
      {"1:2:3:5:PANIC", Reason::ok, 0},
      {"1:2:3:5:working", Reason::out_of_range, 4},
      {"1:2:3:5:WORKINGX", Reason::out_of_range, 4},
      {"1:2:3:5:", Reason::out_of_range, 4},
      {"1:2:3:5:IDLE:", Reason::too_many_params, 5},
      {"1:2:3:5:IDLE:\x01", Reason::too_many_params, 5},  // too many params before the bytes
      {"1:2:3:5:\x01", Reason::non_printable_byte, 4},      // bytes before the kind
      // ACK: u32
      {"1:2:3:3:0", Reason::ok, 0},
      {"1:2:3:3:4294967295", Reason::ok, 0},
      {"1:2:3:3:4294967296", Reason::out_of_range, 4},
      {"1:2:3:3:99999999999999999999999999", Reason::out_of_range, 4},
      {"1:2:3:3:01", Reason::bad_number, 4},
      {"1:2:3:3:", Reason::bad_number, 4},
      {"1:2:3:3:-1", Reason::bad_number, 4},
      {"1:2:3:3:1 ", Reason::bad_number, 4},
      {"1:2:3:3:%0A", Reason::bad_number, 4},   // a valid escape, then not a number
      {"1:2:3:3:%31", Reason::bad_escape, 4},   // '1' escaped: bad escape before the kind
      {"1:2:3:3:1\x01", Reason::non_printable_byte, 4},
      {"1:2:3:3:", Reason::bad_number, 4},
      // MASTER: u16
      {"1:2:3:2:65535", Reason::ok, 0},
      {"1:2:3:2:65536", Reason::out_of_range, 4},
      {"1:2:3:2:x", Reason::bad_number, 4},
      // NOT: u32, text
      {"1:2:3:4:5:wrong state", Reason::ok, 0},
      {"1:2:3:4:5", Reason::too_few_fields, 5},
      {"1:2:3:4:5:", Reason::ok, 0},
      {"1:2:3:4:x:reason", Reason::bad_number, 4},
      {"1:2:3:4:5:r:", Reason::too_many_params, 6},
      // ACTION_*: u32 first
      {"1:2:3:15:7", Reason::ok, 0},
      {"1:2:3:16:7:TOUCH", Reason::ok, 0},
      {"1:2:3:17:4294967296:x", Reason::out_of_range, 4},
      // AGENT: text
      {"1:0:0:1:A", Reason::ok, 0},
      {"1:0:0:1", Reason::too_few_fields, 4},
      // no-param types
      {"1:2:3:9", Reason::ok, 0},
      {"1:2:3:14:x", Reason::too_many_params, 4},
      {"1:0:3:19", Reason::ok, 0},
      // SENSOR_VALUE: 3..32
      {"1:2:3:18:1:COL-COLOR", Reason::too_few_fields, 6},
      {"1:2:3:18:1:COL-COLOR:5", Reason::ok, 0},
      {"1:2:3:18", Reason::too_few_fields, 4},
      // EVENT: 1..32
      {"1:2:3:20:BATTERY_LOW", Reason::ok, 0},
      {"1:2:3:20", Reason::too_few_fields, 4},
  };
  for (const Case& c : cases) expect_decode(c);

  Message m;
  ASSERT_TRUE(decode("1:2:3:4:4294967295:no", m).ok());
  EXPECT_EQ(m.param_u32(0), 4294967295u);
  EXPECT_EQ(m.param_u32(1), std::nullopt);
  EXPECT_EQ(m.param_u32(2), std::nullopt);
  EXPECT_EQ(m.param_u16(0), std::nullopt);
  ASSERT_TRUE(decode("1:2:3:2:65535", m).ok());
  EXPECT_EQ(m.param_u16(0), 65535);
  EXPECT_EQ(m.param_state(0), std::nullopt);
}

TEST(Decode, ParamCountLimits) {
  for (int type : {7, 18, 20}) {
    const std::string head = "1:2:3:" + std::to_string(type);
    expect_decode({head + params_of(32, "v"), Reason::ok, 0});
    expect_decode({head + params_of(33, "v"), Reason::too_many_params, 36});
    expect_decode({head + params_of(40, "v"), Reason::too_many_params, 36});
    expect_decode({head + params_of(32, "v") + ":\x01", Reason::too_many_params, 36});
  }
  Message m;
  ASSERT_TRUE(decode("1:2:3:7" + params_of(32, "v"), m).ok());
  EXPECT_EQ(m.param_count(), 32u);
  // Per-type min and max for every row of the table.
  for (const MessageSpec& s : kMessageTable) {
    const std::string head = "1:2:3:" + std::to_string(s.type);
    auto valid = [&](std::size_t i) -> std::string {
      switch (s.kind(i)) {
        case ParamKind::u16:
        case ParamKind::u32: return "1";
        case ParamKind::state: return "IDLE";
        case ParamKind::text: return "t";
      }
      return "";
    };
    auto with = [&](std::size_t n) {
      std::string d = head;
      for (std::size_t i = 0; i < n; ++i) d += ":" + valid(i);
      return d;
    };
    expect_decode({with(s.min_params), Reason::ok, 0});
    expect_decode({with(s.max_params), Reason::ok, 0});
    if (s.min_params > 0) expect_decode({with(s.min_params - 1u), Reason::too_few_fields, 4u + s.min_params - 1u});
    expect_decode({with(s.max_params) + ":t", Reason::too_many_params, 4u + s.max_params});
  }
}

TEST(Decode, DoesNotReadPastTheInput) {
  // The datagram is a prefix of a longer buffer whose next bytes would make it valid or different.
  const std::string buf = "1:2:3:3:12345:more";
  Message m;
  ASSERT_TRUE(decode(std::string_view(buf.data(), 11), m).ok());  // "1:2:3:3:123"
  EXPECT_EQ(m.param(0), "123");
  EXPECT_EQ(decode(std::string_view(buf.data(), 7), m), (DecodeResult{Reason::too_few_fields, 4}));  // "1:2:3:3"
  const std::string pct = "1:2:3:7:%3A";
  EXPECT_EQ(decode(std::string_view(pct.data(), pct.size() - 1), m), (DecodeResult{Reason::bad_escape, 4}));
}

TEST(Message, IsTriviallyCopyableAndSelfContained) {
  static_assert(std::is_trivially_copyable<Message>::value);
  Message a;
  std::string d = "1:2:3:7:name:k=v";
  ASSERT_TRUE(decode(d, a).ok());
  Message b = a;
  d.assign(d.size(), 'x');  // the datagram's bytes are gone; b holds its own copy
  EXPECT_EQ(b.param(0), "name");
  EXPECT_EQ(b.param(1), "k=v");
  EXPECT_EQ(a, b);
  b.msgid = 4;
  EXPECT_NE(a, b);
}

TEST(Message, BuildersAndLimits) {
  Message m(7, 1, 12, MsgType::PING);
  EXPECT_EQ(m.param_count(), 0u);
  ASSERT_TRUE(m.add_param_state(AgentState::WORKING));
  char buf[64];
  EncodeResult e = encode(m, buf, sizeof buf);
  ASSERT_TRUE(e.ok());
  EXPECT_EQ(std::string(buf, e.size), "7:1:12:5:WORKING");

  Message n(1, 2, 3, MsgType::NOT);
  ASSERT_TRUE(n.add_param_u32(4294967295u));
  ASSERT_TRUE(n.add_param("a:b%"));
  e = encode(n, buf, sizeof buf);
  ASSERT_TRUE(e.ok());
  EXPECT_EQ(std::string(buf, e.size), "1:2:3:4:4294967295:a%3Ab%25");
  Message z;
  ASSERT_TRUE(z.add_param_u32(0));
  EXPECT_EQ(z.param(0), "0");

  Message big(1, 2, 3, MsgType::BEHAVIOUR);
  for (std::size_t i = 0; i < kMaxParams; ++i) ASSERT_TRUE(big.add_param("x"));
  EXPECT_FALSE(big.add_param("x"));
  EXPECT_EQ(big.param_count(), kMaxParams);
  big.clear_params();
  EXPECT_EQ(big.param_count(), 0u);
  ASSERT_TRUE(big.add_param(std::string(Message::kCapacity - 1, 'a')));
  EXPECT_FALSE(big.add_param("bb"));
  EXPECT_TRUE(big.add_param("b"));
  EXPECT_TRUE(big.add_param(""));
  EXPECT_EQ(big.params_size(), Message::kCapacity);
}

TEST(Encode, Refusals) {
  char buf[kMaxDatagram];
  auto refused = [&](const Message& m, Reason r, unsigned field) {
    std::memset(buf, '#', sizeof buf);
    const EncodeResult e = encode(m, buf, sizeof buf);
    EXPECT_EQ(to_string(e.reason), to_string(r));
    EXPECT_EQ(unsigned{e.field}, field);
    EXPECT_EQ(e.size, 0u);
    EXPECT_EQ(buf[0], '#') << "encode wrote although it refused";
  };
  refused(Message(1, 2, 3, static_cast<MsgType>(0)), Reason::out_of_range, 3);
  refused(Message(1, 2, 3, static_cast<MsgType>(34)), Reason::unknown_type, 3);
  refused(Message(1, 2, 3, static_cast<MsgType>(255)), Reason::unknown_type, 3);
  refused(Message(1, 2, 3, MsgType::PING), Reason::too_few_fields, 4);
  Message ping(1, 2, 3, MsgType::PING);
  ping.add_param("SLEEPING");
  refused(ping, Reason::out_of_range, 4);
  ping.clear_params();
  ping.add_param("IDLE");
  ping.add_param("IDLE");
  refused(ping, Reason::too_many_params, 5);
  Message ack(1, 2, 3, MsgType::ACK);
  ack.add_param("007");
  refused(ack, Reason::bad_number, 4);
  ack.clear_params();
  ack.add_param("4294967296");
  refused(ack, Reason::out_of_range, 4);
  Message master(1, 2, 3, MsgType::MASTER);
  master.add_param("65536");
  refused(master, Reason::out_of_range, 4);
  Message start(1, 2, 3, MsgType::START);
  start.add_param("");
  refused(start, Reason::too_many_params, 4);
  Message sensor(1, 2, 3, MsgType::SENSOR_VALUE);
  sensor.add_param("1");
  sensor.add_param("m");
  refused(sensor, Reason::too_few_fields, 6);
  // Too long: 1500 ':' escape to 4500 bytes. Reported before anything else (as decode would).
  Message huge(1, 2, 3, MsgType::BEHAVIOUR);
  huge.add_param(std::string(1500, ':'));
  refused(huge, Reason::too_long, 0);
  Message huge_ping(1, 2, 3, static_cast<MsgType>(0));
  huge_ping.add_param(std::string(1500, ':'));
  refused(huge_ping, Reason::too_long, 0);
}

TEST(Encode, LengthBoundaryAndCapacity) {
  // "1:2:3:7:" is 8 bytes; a param of 4088 plain bytes makes exactly 4096.
  Message m(1, 2, 3, MsgType::BEHAVIOUR);
  m.add_param(std::string(4088, 'a'));
  std::vector<char> buf(5000, '#');
  EncodeResult e = encode(m, buf.data(), buf.size());
  ASSERT_TRUE(e.ok());
  EXPECT_EQ(e.size, 4096u);
  EXPECT_EQ(buf[4096], '#');
  // One byte more is too long.
  m.clear_params();
  m.add_param(std::string(4089, 'a'));
  e = encode(m, buf.data(), buf.size());
  EXPECT_EQ(e.reason, Reason::too_long);
  EXPECT_EQ(e.field, 0);
  // Escapes count three bytes each: 4086 'a' + one '%' (3 bytes) = 4089 + 8 > 4096.
  m.clear_params();
  m.add_param(std::string(4085, 'a') + "%");
  e = encode(m, buf.data(), buf.size());
  ASSERT_TRUE(e.ok());
  EXPECT_EQ(e.size, 4096u);
  m.clear_params();
  m.add_param(std::string(4086, 'a') + "%");
  EXPECT_EQ(encode(m, buf.data(), buf.size()).reason, Reason::too_long);
  // A valid message longer than the caller's buffer: too long, nothing written past cap.
  Message p(7, 1, 12, MsgType::PING);
  p.add_param("WORKING");
  std::fill(buf.begin(), buf.end(), '#');
  e = encode(p, buf.data(), 15);
  EXPECT_EQ(e.reason, Reason::too_long);
  EXPECT_EQ(e.field, 0);
  EXPECT_EQ(buf[0], '#');
  e = encode(p, buf.data(), 16);
  ASSERT_TRUE(e.ok());
  EXPECT_EQ(e.size, 16u);
  EXPECT_EQ(buf[16], '#');
}

TEST(Encode, CanonicalEscapes) {
  Message m(1, 2, 3, MsgType::BEHAVIOUR);
  std::string all;
  for (int c = 0; c < 256; ++c) all += static_cast<char>(c);
  m.add_param(all);
  char buf[kMaxDatagram];
  const EncodeResult e = encode(m, buf, sizeof buf);
  ASSERT_TRUE(e.ok());
  const std::string out(buf, e.size);
  std::string expect = "1:2:3:7:";
  for (int c = 0; c < 256; ++c) {
    if (c < 0x20 || c > 0x7E || c == ':' || c == '%') {
      char b[4];
      std::snprintf(b, sizeof b, "%%%02X", c);
      expect += b;
    } else {
      expect += static_cast<char>(c);
    }
  }
  EXPECT_EQ(out, expect);
  Message back;
  ASSERT_TRUE(decode(out, back).ok());
  EXPECT_EQ(back, m);
}

// Random messages with every kind of param: encode, decode gives them back, re-encode is identical.
TEST(RoundTrip, RandomMessages) {
  std::mt19937 rng(12345);
  auto pick = [&](std::uint32_t n) { return static_cast<std::uint32_t>(rng() % n); };
  const char* states[] = {"IDLE", "ACTIVE", "WORKING", "PAUSED", "PANIC"};
  char buf[kMaxDatagram];
  char buf2[kMaxDatagram];
  int encoded = 0;
  for (int iter = 0; iter < 20000; ++iter) {
    const MessageSpec& s = kMessageTable[pick(kMessageTableSize)];
    Message m(static_cast<std::uint16_t>(rng()), static_cast<std::uint16_t>(rng()),
              iter % 7 == 0 ? 4294967295u : static_cast<std::uint32_t>(rng()), static_cast<MsgType>(s.type));
    const std::size_t n = s.min_params + pick(s.max_params - s.min_params + 1u);
    for (std::size_t i = 0; i < n; ++i) {
      switch (s.kind(i)) {
        case ParamKind::u16: m.add_param_u32(pick(65536)); break;
        case ParamKind::u32: m.add_param_u32(static_cast<std::uint32_t>(rng())); break;
        case ParamKind::state: m.add_param(states[pick(5)]); break;
        case ParamKind::text: {
          std::string v(pick(iter % 50 == 0 ? 400 : 12), 'x');
          for (char& c : v) c = static_cast<char>(pick(4) == 0 ? pick(256) : 0x20 + pick(95));
          m.add_param(v);
          break;
        }
      }
    }
    const EncodeResult e = encode(m, buf, sizeof buf);
    if (!e.ok()) {
      ASSERT_EQ(e.reason, Reason::too_long);
      continue;
    }
    ++encoded;
    Message back;
    const DecodeResult d = decode(std::string_view(buf, e.size), back);
    ASSERT_TRUE(d.ok()) << to_string(d.reason) << " at " << int{d.field} << ": " << show(std::string(buf, e.size));
    ASSERT_EQ(back, m);
    const EncodeResult e2 = encode(back, buf2, sizeof buf2);
    ASSERT_TRUE(e2.ok());
    ASSERT_EQ(std::string(buf, e.size), std::string(buf2, e2.size));
  }
  EXPECT_GT(encoded, 19000);
}

// Random datagrams over a small alphabet of interesting bytes: every accepted one re-encodes to itself.
TEST(RoundTrip, RandomDatagramsAreCanonicalWhenAccepted) {
  std::mt19937 rng(777);
  const std::string alphabet[] = {"0", "1", "5", "7", "18", "3", ":", "%", "%3A", "%25", "%0A", "%41", "%3a",
                                  "A", "IDLE", "x", " ", "\x01", "\x7f", "\xff", "4294967295", "65535", "65536"};
  const std::size_t na = sizeof alphabet / sizeof alphabet[0];
  char buf[kMaxDatagram];
  int accepted = 0;
  for (int iter = 0; iter < 200000; ++iter) {
    std::string d = std::to_string(rng() % 3) + ":" + std::to_string(rng() % 3) + ":" + std::to_string(rng() % 3) +
                    ":" + std::to_string(1 + rng() % 32);
    const std::size_t parts = rng() % 8;
    for (std::size_t i = 0; i < parts; ++i) d += alphabet[rng() % na];
    if (rng() % 8 == 0) d = d.substr(rng() % d.size());
    Message m;
    const DecodeResult r = decode(d, m);
    if (!r.ok()) {
      ASSERT_NE(to_string(r.reason), "");
      ASSERT_LE(r.field, 4u + kMaxParams);
      continue;
    }
    ++accepted;
    const EncodeResult e = encode(m, buf, sizeof buf);
    ASSERT_TRUE(e.ok()) << show(d);
    ASSERT_EQ(std::string(buf, e.size), d);
  }
  EXPECT_GT(accepted, 1000);
}

} // namespace

// Values of every length 0-69 with every mix of plain and escaped bytes: escaped_size() counts
// one byte per byte and three per byte the protocol escapes (':' '%' and bytes outside 0x20..0x7E,
// spelled out here, not taken from the library), encode() writes exactly that many, and decode()
// gives the value back. The values are exactly sized buffers: ASan would see a read outside them.
TEST(Encode, EscapedSizeAndRoundTripEveryLength) {
  std::mt19937 rng(20261126);
  std::vector<char> buf;
  for (int iter = 0; iter < 20000; ++iter) {
    const std::size_t size = rng() % 70u;
    const unsigned special = 1u + static_cast<unsigned>(rng() % 24u);
    buf.assign(size, 'a');
    for (auto& c : buf) {
      const unsigned x = static_cast<unsigned>(rng());
      c = static_cast<char>(x % special == 0 ? (x >> 8) & 0xFFu : 'a' + (x >> 8) % 26u);
    }
    std::size_t want = size;
    for (char ch : buf) {
      const auto c = static_cast<unsigned char>(ch);
      if (c < 0x20 || c > 0x7E || c == ':' || c == '%') want += 2u;
    }
    ASSERT_EQ(ev3proto::escaped_size(std::string_view(buf.data(), size)), want) << "size " << size;

    const std::string_view params[2] = {std::string_view(buf.data(), size), "x"};
    char out[256];
    const auto r = ev3proto::encode_parts(7, 1, 3, 7 /* BEHAVIOUR: text params */, params, 2, out, sizeof out);
    ASSERT_TRUE(r.ok()) << "size " << size;
    ASSERT_EQ(r.size, std::string_view("7:1:3:7:").size() + want + 2u) << "size " << size;
    ev3proto::Message m;
    ASSERT_TRUE(ev3proto::decode(std::string_view(out, r.size), m).ok()) << std::string_view(out, r.size);
    ASSERT_EQ(m.param(0), params[0]) << "size " << size;
  }
}
