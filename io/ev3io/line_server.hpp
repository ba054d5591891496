/// @file line_server.hpp
/// @brief A Unix stream socket that takes lines and gives lines back (ev3-master's `--control`):
///        non-blocking, polled by the program's one event loop, at most kMaxClients connections.
#pragma once

#include <poll.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace ev3io {

class LineServer {
 public:
  using Client = std::uint32_t;  ///< 1, 2, ...: a connection; never reused while the server runs
  static constexpr std::size_t kMaxClients = 8;
  static constexpr std::size_t kMaxLine = 65536;      ///< a longer line is refused, the client kept
  static constexpr std::size_t kMaxPending = 1 << 20;  ///< answers a client does not read: closed above

  LineServer() = default;
  LineServer(const LineServer&) = delete;
  LineServer& operator=(const LineServer&) = delete;
  ~LineServer();

  /// Listens on @p path, mode 0600, or 0660 and group @p group when given. A socket file left by
  /// a program that is gone is replaced; a live one, or a file that is no socket, is not. Returns
  /// "" or the error naming the path (or the group).
  std::string open(const std::string& path, const std::string& group);
  /// Closes every connection and removes the socket file.
  void close();
  bool is_open() const noexcept { return fd_ >= 0; }

  /// The descriptors to poll (the listener, then each connection); at most 1 + kMaxClients.
  std::size_t fds(pollfd* out) const;
  /// After poll: accepts, reads, writes what is owed. @p on_line gets each complete line (without
  /// its newline); a line over kMaxLine gets @p too_long's answer instead.
  void serve(const pollfd* fds, std::size_t n, const std::function<void(Client, const std::string&)>& on_line,
             const std::function<std::string()>& too_long);
  /// Client @p c is gone (closed by it, or by us). Called from serve().
  std::function<void(Client)> on_close;
  /// Whether client @p c still waits for answers: a client that closed its side of the connection
  /// (`echo cmd | socat ...`) keeps it until they are written.
  std::function<bool(Client)> busy;

  /// Queues @p line and a newline for @p c (dropped when @p c is gone).
  void send(Client c, const std::string& line);

 private:
  struct Conn {
    int fd = -1;
    Client id = 0;
    std::string in, out;
    bool skipping = false;  ///< inside a line over kMaxLine: dropped up to its newline
    bool eof = false;       ///< the client closed its side: no more lines, answers still go out
  };
  void drop(std::size_t i);
  /// Drops connection @p i if it is done: broken, or closed by the client with nothing owed.
  bool reap(std::size_t i);
  void flush(Conn& c);
  int fd_ = -1;
  std::string path_;
  Client next_ = 1;
  std::vector<Conn> conns_;
};

}  // namespace ev3io
