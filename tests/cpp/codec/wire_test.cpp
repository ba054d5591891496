// decode/encode of wire format v1 against docs/protocol.md: every rejection with its field, the
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

// decode() classifies 64-byte blocks with SSE2 on x86 and SWAR elsewhere (the EV3): every variant
// compiled here must agree with the byte-at-a-time reference on every byte value and position.
TEST(Classify, VariantsAgreeWithScalarReference) {
  std::mt19937 rng(20261121);
  unsigned char block[64];
  for (int iter = 0; iter < 20000; ++iter) {
    for (auto& b : block) {
      // Half the bytes near the boundaries (0x1F/0x20, 0x7E/0x7F, ':' '%'), half anything.
      static constexpr unsigned char kEdges[] = {0x00, 0x1F, 0x20, 0x21, 0x24, 0x25, 0x26, 0x39, 0x3A,
                                                 0x3B, 0x7E, 0x7F, 0x80, 0xDF, 0xE0, 0xFF};
      b = (rng() & 1u) ? kEdges[rng() % sizeof kEdges] : static_cast<unsigned char>(rng());
    }
    for (std::size_t len = 16; len <= 64; len += 16) {
      std::uint64_t rc = 0, rs = 0;
      ev3proto::detail::classify_scalar(block, len, rc, rs);
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
      std::uint64_t wc = 0, ws = 0;
      ev3proto::detail::classify_swar(block, len, wc, ws);
      ASSERT_EQ(wc, rc) << "swar colons, len " << len;
      ASSERT_EQ(ws, rs) << "swar specials, len " << len;
#endif
#if defined(__SSE2__)
      std::uint64_t sc = 0, ss = 0;
      ev3proto::detail::classify_sse2(block, len, sc, ss);
      ASSERT_EQ(sc, rc) << "sse2 colons, len " << len;
      ASSERT_EQ(ss, rs) << "sse2 specials, len " << len;
#endif
    }
  }
}

// copy_classify_generic(): one memcpy, padding to 16 bytes with 'A', and classify_scalar()'s masks
// of every 64-byte block of the padded region, for every length.
TEST(Classify, GenericRegionAgreesWithScalarReference) {
  std::mt19937 rng(20261122);
  std::vector<unsigned char> src;
  alignas(64) unsigned char g[ev3proto::kMaxDatagram];
  std::uint64_t gc[64], gs[64];
  for (int iter = 0; iter < 600; ++iter) {
    const std::size_t n = rng() % 4089u;  // a param region is at most 4088 bytes
    src.assign(n, 0);  // exactly n bytes: ASan would see a read past them
    for (auto& b : src) b = static_cast<unsigned char>((rng() % 4u == 0) ? ':' : rng());
    ev3proto::detail::copy_classify_generic(src.data(), n, g, gc, gs);
    ASSERT_EQ(0, n ? std::memcmp(g, src.data(), n) : 0) << "generic copy, n " << n;
    const std::size_t padded = (n + 15u) & ~std::size_t{15};
    for (std::size_t i = n; i < padded; ++i) ASSERT_EQ(g[i], 'A') << "padding, n " << n;
    const std::size_t blocks = (padded + 63u) / 64u;
    for (std::size_t k = 0; k < blocks; ++k) {
      std::uint64_t rc = 0, rs = 0;
      const std::size_t span = padded - 64u * k < 64u ? padded - 64u * k : 64u;
      ev3proto::detail::classify_scalar(g + 64u * k, span, rc, rs);
      ASSERT_EQ(gc[k], rc) << "generic colons, block " << k << ", n " << n;
      ASSERT_EQ(gs[k], rs) << "generic specials, block " << k << ", n " << n;
    }
  }
}

#if defined(__SSE2__)  // x86 only: elsewhere (the EV3) decode() has the portable scan alone
// decode()'s scan of the param region (scan_params()): the small-region path (SSE2, at most 64
// bytes) and the AVX2 and AVX-512 ones (64 bytes and more, where the CPU has them) must copy the
// same bytes and give the same ':' positions (up to the cap), special masks and special blocks as
// the portable one, for every length, colon density and cap, writing nothing past the n bytes. The
// source is exactly the bytes that may be read (the region, and 16 bytes before its end for the
// small path): ASan would see a read past them.
TEST(Classify, ScanVariantsAgree) {
  std::mt19937 rng(20261125);
  std::vector<unsigned char> buf;
  alignas(64) unsigned char g[ev3proto::kMaxDatagram], v[ev3proto::kMaxDatagram];
  std::uint64_t gs[64], vs[64];
  std::uint16_t ga[ev3proto::kMaxParams + 32], va[ev3proto::kMaxParams + 32];
  int small_runs = 0, avx2_runs = 0;
  for (int iter = 0; iter < 4000; ++iter) {
    const std::size_t n = iter % 2 ? rng() % 200u : rng() % 4089u;
    const std::size_t before = n < 16u ? 16u - n : 0u;
    const unsigned density = 1u + rng() % 64u;  // one ':' in `density` bytes on average
    const unsigned special = 1u + rng() % 128u;
    buf.assign(before + n, 0);
    for (auto& b : buf) {
      const unsigned x = static_cast<unsigned>(rng());
      b = static_cast<unsigned char>(x % density == 0 ? ':' : x % special == 0 ? (x >> 8) : 'a' + (x >> 8) % 26u);
    }
    const unsigned char* src = buf.data() + before;
    const std::size_t cap = 1u + rng() % ev3proto::kMaxParams;
    const ev3proto::detail::Scan want = ev3proto::detail::scan_generic(src, n, g, cap, ga, gs);
    const std::size_t blocks = (n + 63u) / 64u;
    auto same = [&](const ev3proto::detail::Scan& got, const char* what) {
      ASSERT_EQ(0, n ? std::memcmp(v, src, n) : 0) << what << " copy, n " << n;
      for (std::size_t i = n; i < n + 80u && i < sizeof v; ++i) ASSERT_EQ(v[i], 0xEE) << what << " wrote past n " << n;
      ASSERT_EQ(got.colons_seen, want.colons_seen) << what << ", n " << n << ", cap " << cap;
      for (std::size_t j = 0; j < want.colons_seen; ++j) ASSERT_EQ(va[j], ga[j]) << what << " position " << j;
      ASSERT_EQ(got.special_blocks, want.special_blocks) << what << ", n " << n;
      for (std::size_t k = 0; k < blocks; ++k) ASSERT_EQ(vs[k], gs[k]) << what << " specials, block " << k;
    };
    if (n <= 64u) {
      ++small_runs;
      std::memset(v, 0xEE, sizeof v);
      same(ev3proto::detail::scan_small_sse2(src, n, v, cap, va, vs), "small");
    }
#if defined(EV3PROTO_AVX2_DISPATCH)
    if (n >= 64u && ev3proto::detail::cpu_has_avx2()) {
      ++avx2_runs;
      std::memset(v, 0xEE, sizeof v);
      same(ev3proto::detail::scan_avx2(src, n, v, cap, va, vs), "avx2");
    }
    if (n >= 64u && ev3proto::detail::cpu_has_avx512_scan()) {
      std::memset(v, 0xEE, sizeof v);
      same(ev3proto::detail::scan_avx512(src, n, v, cap, va, vs), "avx512");
    }
#endif
    if (::testing::Test::HasFatalFailure()) return;
  }
  EXPECT_GT(small_runs, 100);
  (void)avx2_runs;
}
#endif

#if defined(__SSE2__)
// decode() checks a header that ends, with its ':' after the type, in the first 16 bytes all at once
// (header_sse2()) and falls back to the byte-at-a-time check otherwise. The fast check may only accept
// what the bytewise one accepts, with the same values and param offset, and it must accept every
// such header that fits (else it would be dead code). Headers are built field by field from digit
// strings of every length 0 to 11 with and without leading zeros, values at and past each maximum,
// and a stray byte now and then; each is followed by enough bytes to make 16 or more, exactly sized.
TEST(Classify, HeaderFastPathAgreesWithBytewise) {
  std::mt19937 rng(20261121);
  const char* const edge[] = {"0", "00", "01", "1", "9", "255", "256", "65535", "65536", "4294967295",
                              "4294967296", "99999999999", "", "12a", "-1", " 1"};
  auto piece = [&]() -> std::string {
    const unsigned pick = static_cast<unsigned>(rng() % 4u);
    if (pick == 0) return edge[rng() % (sizeof edge / sizeof edge[0])];
    std::string s;
    const std::size_t len = pick == 1 ? 1u + rng() % 3u : rng() % 12u;
    for (std::size_t i = 0; i < len; ++i) s += static_cast<char>('0' + rng() % 10u);
    return s;
  };
  int accepted = 0, fast = 0;
  for (int iter = 0; iter < 200000; ++iter) {
    std::string h = piece() + ":" + piece() + ":" + piece() + ":" + piece();
    if (rng() % 8u != 0) h += ":";
    if (rng() % 16u == 0) h[rng() % h.size()] = static_cast<char>(rng() % 256u);
    while (h.size() < 16u || rng() % 4u == 0) h += static_cast<char>(' ' + rng() % 95u);
    const std::vector<char> bytes(h.begin(), h.end());  // exactly sized: ASan sees a read past it
    std::uint32_t want[4] = {9, 9, 9, 9}, got[4] = {7, 7, 7, 7};
    std::size_t want_at = 0, got_at = 0;
    const ev3proto::DecodeResult r = ev3proto::detail::header_bytewise(bytes.data(), bytes.size(), want, want_at);
    const bool took = ev3proto::detail::header_sse2(bytes.data(), got, got_at);
    if (took) {
      ++fast;
      ASSERT_TRUE(r.ok()) << h;
      ASSERT_EQ(got_at, want_at) << h;
      for (int k = 0; k < 4; ++k) ASSERT_EQ(got[k], want[k]) << h << " field " << k;
    } else if (r.ok()) {
      ASSERT_TRUE(want_at == 0 || want_at > 16u) << "the fast check refused a header that fits: " << h;
    }
    accepted += r.ok();
  }
  EXPECT_GT(fast, 1000);
  EXPECT_GT(accepted, fast);
}
#endif

// encode() sizes and writes the last bytes of a value from the 16 bytes ending it, or from two
// overlapping words: the masks must be the byte-at-a-time ones, escaped_size() the plain count, and
// encode() of a message with such values must round-trip, for every length and mix of bytes. The
// values are exactly sized buffers: ASan would see a read outside them.
TEST(Classify, ShortAndTailEscapeMasks) {
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
    for (char c : buf) want += ev3proto::detail::must_escape(static_cast<unsigned char>(c)) ? 2u : 0u;
    ASSERT_EQ(ev3proto::escaped_size(std::string_view(buf.data(), size)), want) << "size " << size;
    const std::size_t rest = size % 16u;
    std::uint32_t ref = 0;
    for (std::size_t i = 0; i < rest; ++i)
      ref |= std::uint32_t{ev3proto::detail::must_escape(static_cast<unsigned char>(buf[size - rest + i]))} << i;
    ASSERT_EQ(ev3proto::detail::tail_escape_mask(buf.data(), size, rest), ref) << "size " << size;
    if (size < 16u) {
      ASSERT_EQ(ev3proto::detail::escape_mask_short(buf.data(), size), ref) << "size " << size;
    }

    const std::string_view params[2] = {std::string_view(buf.data(), size), "x"};
    char out[256];
    const auto r = ev3proto::encode_parts(7, 1, 3, 7 /* BEHAVIOUR: text params */, params, 2, out, sizeof out);
    ASSERT_TRUE(r.ok()) << "size " << size;
    ev3proto::Message m;
    ASSERT_TRUE(ev3proto::decode(std::string_view(out, r.size), m).ok()) << std::string_view(out, r.size);
    ASSERT_EQ(m.param(0), params[0]) << "size " << size;
  }
}

// Unescaping moves bytes left inside the message buffer with move_left(): it must equal memmove for
// every length and every distance, including the overlapping ones, and write nothing past the end.
TEST(Classify, MoveLeftIsMemmoveForLeftMoves) {
  for (std::size_t len = 0; len < 40; ++len) {
    for (std::size_t gap = 0; gap < 20; ++gap) {
      unsigned char a[80], b[80];
      for (std::size_t i = 0; i < sizeof a; ++i) a[i] = b[i] = static_cast<unsigned char>(i * 7u + 1u);
      ev3proto::detail::move_left(a + 3, a + 3 + gap, len);
      std::memmove(b + 3, b + 3 + gap, len);
      ASSERT_EQ(0, std::memcmp(a, b, sizeof a)) << "len " << len << " gap " << gap;
    }
  }
}
