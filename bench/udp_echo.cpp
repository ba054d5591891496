// udp_echo: the floor for ev3-master's throughput (docs/benchmarks.md, "Master throughput against a
// raw UDP echo"). One non-blocking UDP socket; poll() until datagrams wait, then recvmmsg() up to 64
// of them and sendmmsg() each back to its sender, unchanged. No protocol, no state: what handling a
// datagram costs when nothing is done with it but the system calls.
//
//   udp_echo [--bind ADDR] --port N
//
// Runs until SIGINT or SIGTERM, then prints on stderr how many datagrams it echoed.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <cstdint>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace {

volatile std::sig_atomic_t g_stop = 0;
extern "C" void on_signal(int) { g_stop = 1; }

constexpr unsigned kBatch = 64;
constexpr std::size_t kMax = 4096;  // the protocol's largest datagram

int usage() {
  std::fprintf(stderr, "usage: udp_echo [--bind ADDR] --port N\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  const char* bind_addr = "127.0.0.1";
  long port = -1;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--bind") == 0 && i + 1 < argc) {
      bind_addr = argv[++i];
    } else if (std::strcmp(argv[i], "--port") == 0 && i + 1 < argc) {
      char* end = nullptr;
      port = std::strtol(argv[++i], &end, 10);
      if (*end != '\0' || port < 1 || port > 65535) {
        std::fprintf(stderr, "udp_echo: bad value for --port: '%s' (1..65535)\n", argv[i]);
        return 2;
      }
    } else {
      return usage();
    }
  }
  if (port < 0) return usage();
  sockaddr_in sa{};
  sa.sin_family = AF_INET;
  sa.sin_port = htons(static_cast<std::uint16_t>(port));
  if (inet_pton(AF_INET, bind_addr, &sa.sin_addr) != 1) {
    std::fprintf(stderr, "udp_echo: bad value for --bind: '%s'\n", bind_addr);
    return 2;
  }
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0 || bind(fd, reinterpret_cast<sockaddr*>(&sa), sizeof sa) != 0) {
    std::fprintf(stderr, "udp_echo: cannot bind %s:%ld: %s\n", bind_addr, port, std::strerror(errno));
    return 1;
  }
  struct sigaction act {};
  act.sa_handler = on_signal;
  sigaction(SIGINT, &act, nullptr);
  sigaction(SIGTERM, &act, nullptr);

  static std::array<std::array<char, kMax>, kBatch> bufs;
  std::array<sockaddr_in, kBatch> from{};
  std::array<iovec, kBatch> iov{};
  std::array<mmsghdr, kBatch> msgs{};
  unsigned long long echoed = 0;
  while (!g_stop) {
    pollfd p{fd, POLLIN, 0};
    if (poll(&p, 1, 1000) < 0 && errno != EINTR) break;
    for (;;) {
      for (unsigned i = 0; i < kBatch; ++i) {
        iov[i] = {bufs[i].data(), kMax};
        msgs[i] = {};
        msgs[i].msg_hdr.msg_name = &from[i];
        msgs[i].msg_hdr.msg_namelen = sizeof from[i];
        msgs[i].msg_hdr.msg_iov = &iov[i];
        msgs[i].msg_hdr.msg_iovlen = 1;
      }
      const int n = recvmmsg(fd, msgs.data(), kBatch, MSG_DONTWAIT, nullptr);
      if (n <= 0) break;
      for (int i = 0; i < n; ++i) iov[static_cast<unsigned>(i)].iov_len = msgs[static_cast<unsigned>(i)].msg_len;
      int sent = 0;
      while (sent < n) {  // the send buffer full: what is left is dropped, as a busy server would
        const int k = sendmmsg(fd, msgs.data() + sent, static_cast<unsigned>(n - sent), 0);
        if (k <= 0) break;
        sent += k;
      }
      echoed += static_cast<unsigned long long>(sent);
      if (n < static_cast<int>(kBatch)) break;
    }
  }
  std::fprintf(stderr, "udp_echo: %llu datagrams echoed\n", echoed);
  close(fd);
  return 0;
}
