#pragma once

/// @file
/// HttpServer's internals, shared by http_server.cc (binding, workers, routing)
/// and http_connection.cc (accepting, reading, framing, answering and closing
/// connections). Not for other users.

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <poll.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>
#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <iostream>
#include <thread>

#include "server/http/errors.h"
#include "api/json_fields.h"
#include "server/http/request_framing.h"
#include "server/http/request_parser.h"
#include "server/http/response_writer.h"
#include "server/http/http_server.h"
#include "storage/audit_log.h"

namespace fesbench::server::http {

using Clock = std::chrono::steady_clock;

// Two workers beyond max_connections + max_streams, for urgent routes.
inline constexpr std::size_t kUrgentReserve = 2;
// Connections one worker accepts before it gives the listening socket back.
inline constexpr std::size_t kAcceptBatch = 32;
// How long a closed connection keeps reading (and discarding) what the
// client still sends, so that the client reads our last answer instead of
// a reset.
inline constexpr auto kLinger = std::chrono::milliseconds(2000);
inline constexpr std::size_t kReadChunk = 16 * 1024;

// "application/json", parameters and case aside.
inline bool IsJsonContentType(std::string_view value) {
  std::string lower;
  for (char c : value.substr(0, value.find(';'))) {
    if (c != ' ' && c != '\t') lower.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(c))));
  }
  return lower == "application/json";
}

inline std::string AddressText(const sockaddr_storage& addr, int& port) {
  char text[INET6_ADDRSTRLEN] = "";
  if (addr.ss_family == AF_INET) {
    const auto* in = reinterpret_cast<const sockaddr_in*>(&addr);
    ::inet_ntop(AF_INET, &in->sin_addr, text, sizeof text);
    port = ntohs(in->sin_port);
  } else if (addr.ss_family == AF_INET6) {
    const auto* in6 = reinterpret_cast<const sockaddr_in6*>(&addr);
    ::inet_ntop(AF_INET6, &in6->sin6_addr, text, sizeof text);
    port = ntohs(in6->sin6_port);
  }
  return text;
}

// One client connection. Owned by connections_; a worker holds `mutex`
// while it reads, handles or closes it, so at most one thread touches it
// (epoll's one-shot arming hands each readiness event to one worker).
struct HttpServer::Connection {
  std::mutex mutex;
  std::uint64_t id = 0;
  int fd = -1;
  SSL* ssl = nullptr;
  bool handshaken = false;
  std::string in;   ///< received, not yet handled.
  std::string out;  ///< response bytes not yet sent.
  std::string remote_ip, local_ip;
  int remote_port = 0, local_port = 0;
  Clock::time_point deadline;
  bool request_started = false;  ///< `in` holds part of a request.
  bool head_seen = false;
  bool admitted = false;  ///< the pending request's head passed the route, token and role checks.
  HttpServer::Preadmission preadmission;  ///< admitted: its route and user.
  bool continue_sent = false;
  bool urgent_only = false;  ///< accepted with no room left: serves urgent routes only.
  // Spooling an upload: its head is the first `head_length` bytes of `in`;
  // the body goes to `spool_fd` as it arrives.
  int spool_fd = -1;
  std::size_t head_length = 0;
  std::size_t spool_expected = 0;
  std::size_t spool_written = 0;
  Clock::time_point spool_deadline;  ///< the whole body by then.
  bool peer_closed = false;  ///< the client half-closed (FIN read).
  bool lingering = false;    ///< answered and shut down; discarding input.
  bool arriving = false;     ///< EvictOne saw bytes waiting that no worker has read yet.
  bool closed = false;
  std::size_t served = 0;

  // Reads what is available, up to `limit` bytes in `in`. False on a
  // connection error.
  bool ReadAvailable(std::size_t limit) {
    char buffer[kReadChunk];
    while (in.size() < limit) {
      ssize_t n;
      if (ssl) {
        ERR_clear_error();
        n = SSL_read(ssl, buffer, static_cast<int>(sizeof buffer));
        if (n <= 0) {
          const int error = SSL_get_error(ssl, static_cast<int>(n));
          if (error == SSL_ERROR_WANT_READ || error == SSL_ERROR_WANT_WRITE) return true;
          if (error == SSL_ERROR_ZERO_RETURN) {
            peer_closed = true;
            return true;
          }
          return false;
        }
      } else {
        n = ::recv(fd, buffer, sizeof buffer, MSG_DONTWAIT);
        if (n == 0) {
          peer_closed = true;
          return true;
        }
        if (n < 0) return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR;
      }
      in.append(buffer, static_cast<std::size_t>(n));
      if (!ssl && static_cast<std::size_t>(n) < sizeof buffer) return true;  // drained
    }
    return true;
  }

  // Reads and drops what has arrived (bypassing TLS); false once the client
  // closed or the connection failed.
  bool Discard() {
    char buffer[kReadChunk];
    for (;;) {
      const ssize_t n = ::recv(fd, buffer, sizeof buffer, MSG_DONTWAIT);
      if (n == 0) return false;
      if (n < 0) return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR;
    }
  }

  // Waits until the socket is ready for `events` or the timeout passes.
  bool WaitFor(short events, std::chrono::milliseconds timeout) const {
    pollfd p{fd, events, 0};
    int r;
    do {
      r = ::poll(&p, 1, static_cast<int>(timeout.count()));
    } while (r < 0 && errno == EINTR);
    return r > 0 && (p.revents & (POLLERR | POLLNVAL)) == 0;
  }

  // Sends all of `data`, waiting at most `timeout` each time the socket is full.
  bool SendAll(std::string_view data, std::chrono::milliseconds timeout) {
    while (!data.empty()) {
      ssize_t n;
      if (ssl) {
        ERR_clear_error();
        n = SSL_write(ssl, data.data(), static_cast<int>(std::min<std::size_t>(data.size(), 1 << 30)));
        if (n <= 0) {
          const int error = SSL_get_error(ssl, static_cast<int>(n));
          if (error == SSL_ERROR_WANT_WRITE && WaitFor(POLLOUT, timeout)) continue;
          if (error == SSL_ERROR_WANT_READ && WaitFor(POLLIN, timeout)) continue;
          return false;
        }
      } else {
        n = ::send(fd, data.data(), data.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
        if (n < 0) {
          if (errno == EINTR) continue;
          if ((errno == EAGAIN || errno == EWOULDBLOCK) && WaitFor(POLLOUT, timeout)) continue;
          return false;
        }
      }
      data.remove_prefix(static_cast<std::size_t>(n));
    }
    return true;
  }

  bool Flush(std::chrono::milliseconds timeout) {
    const bool ok = SendAll(out, timeout);
    out.clear();
    return ok;
  }

  // Bytes the client sent are waiting to be read.
  bool BytesWaiting() const {
    char byte;
    return ::recv(fd, &byte, 1, MSG_PEEK | MSG_DONTWAIT) > 0;
  }
};

}  // namespace fesbench::server::http
