#include "server/http/http_server_internal.h"

// HttpServer's connections: accepting them, reading and framing requests,
// answering one at a time in order, refusing and closing.

namespace fesbench::server::http {

void HttpServer::Accept() {
  for (;;) {
    sockaddr_storage peer{};
    socklen_t peer_length = sizeof peer;
    const int fd = ::accept4(listen_fd_, reinterpret_cast<sockaddr*>(&peer), &peer_length,
                             SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) {
      if (errno == EINTR || errno == ECONNABORTED) continue;
      if (errno == EMFILE || errno == ENFILE) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
      return;  // EAGAIN: all taken
    }
    const int yes = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &yes, sizeof yes);
    auto c = std::make_shared<Connection>();
    c->fd = fd;
    c->remote_ip = AddressText(peer, c->remote_port);
    sockaddr_storage local{};
    socklen_t local_length = sizeof local;
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&local), &local_length);
    c->local_ip = AddressText(local, c->local_port);
    c->deadline = Clock::now() + options_.keep_alive_timeout;
    bool full = false;
    {
      std::lock_guard lock(connections_mutex_);
      full = connections_.size() >= options_.max_open_connections;
      if (!full) {
        c->id = next_id_++;
        connections_.emplace(c->id, c);
      }
    }
    if (full) {
      const std::string body =
          ErrorJson(HttpError{503, "unavailable", "too many open connections; retry later", {}})
              .dump();
      const std::string response = "HTTP/1.1 503 Service Unavailable\r\nContent-Type: "
                                   "application/json\r\nRetry-After: 1\r\nConnection: close\r\n"
                                   "Content-Length: " +
                                   std::to_string(body.size()) + "\r\n\r\n" + body;
      if (!tls_) c->SendAll(response, std::chrono::milliseconds(0));
      ::shutdown(fd, SHUT_WR);
      ::close(fd);
      continue;
    }
    std::lock_guard lock(c->mutex);
    if (tls_) {
      c->ssl = SSL_new(tls_);
      if (!c->ssl || SSL_set_fd(c->ssl, fd) != 1) {
        Close(*c, false);
        continue;
      }
    }
    epoll_event event{};
    event.events = EPOLLIN | EPOLLONESHOT;
    event.data.u64 = c->id;
    if (::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, fd, &event) != 0) Close(*c, false);
  }
}

void HttpServer::Serve(std::uint64_t id) {
  std::shared_ptr<Connection> c;
  {
    std::lock_guard lock(connections_mutex_);
    auto it = connections_.find(id);
    if (it == connections_.end()) return;
    c = it->second;
  }
  std::lock_guard lock(c->mutex);
  if (c->closed) return;
  if (c->lingering) {
    // Discard what the client still sends; close at its FIN or the deadline.
    if (c->Discard()) {
      Rearm(*c);
    } else {
      Close(*c, false);
    }
    return;
  }
  if (c->ssl && !c->handshaken) {
    ERR_clear_error();
    const int r = SSL_accept(c->ssl);
    if (r == 1) {
      c->handshaken = true;
    } else {
      const int error = SSL_get_error(c->ssl, r);
      if (error == SSL_ERROR_WANT_READ || error == SSL_ERROR_WANT_WRITE) {
        if (!c->request_started) {
          c->request_started = true;  // the handshake counts against the request deadline
          c->deadline = Clock::now() + options_.request_timeout;
        }
        Rearm(*c, error == SSL_ERROR_WANT_WRITE);
      } else {
        Close(*c, false);
      }
      return;
    }
  }
  HandleBytes(*c);
}

void HttpServer::HandleBytes(Connection& c) {
  FramingLimits limits;
  limits.max_head_bytes = options_.max_head_bytes;
  limits.max_headers = options_.max_headers;
  limits.max_body_bytes = options_.max_body_bytes;
  limits.max_upload_bytes = options_.max_upload_bytes;
  // Read no further than one whole request beyond a full one: pipelined
  // requests wait in the kernel until their turn. An upload's head raises
  // the limit to its own length.
  std::size_t read_limit = options_.max_head_bytes + options_.max_body_bytes + kReadChunk;
  if (!c.in.empty()) {
    const Framing pending = FrameRequest(c.in, limits);
    if (pending.head_complete && IsUpload(pending.method, pending.path)) {
      read_limit = std::max(read_limit, pending.total() + kReadChunk);
    }
  }
  for (;;) {
    if (!c.ReadAvailable(read_limit)) {
      Close(c, false);
      return;
    }
    bool handled_any = false;  // (read again only for TLS-buffered bytes)
    while (!c.in.empty()) {
      const Framing f = FrameRequest(c.in, limits);
      if (f.state == Framing::State::kError) {
        Refuse(c, f.error, true);
        return;
      }
      if (f.state == Framing::State::kIncomplete) {
        const auto now = Clock::now();
        if (!c.request_started) {
          c.request_started = true;
          c.deadline = now + options_.request_timeout;
        }
        const bool upload = f.head_complete && IsUpload(f.method, f.path);
        if (upload) read_limit = std::max(read_limit, f.total() + kReadChunk);
        if (f.head_complete && !c.head_seen) {
          c.head_seen = true;
          // A body gets as long again as the head had; an upload one more
          // second per MiB.
          auto allowance = options_.request_timeout;
          if (upload) allowance += std::chrono::seconds(f.body_bytes >> 20);
          c.deadline = std::max(c.deadline, now + allowance);
        }
        if (f.head_complete && f.expect_continue && !c.continue_sent) {
          c.continue_sent = true;
          if (!c.SendAll("HTTP/1.1 100 Continue\r\n\r\n", options_.write_timeout)) {
            Close(c, false);
            return;
          }
        }
        break;
      }
      const bool urgent = IsUrgent(f.method, f.path);
      const bool more_allowed = c.served + 1 < options_.keep_alive_max_count &&
                                !stop_requested_.load() && !(c.peer_closed && c.in.size() == f.total());
      const bool last = !f.keep_alive || !more_allowed;
      bool keep;
      if (!urgent && busy_.load() >= workers_ - kUrgentReserve) {
        Refuse(c,
               HttpError{503, "unavailable",
                         "the server is handling " + std::to_string(busy_.load()) +
                             " requests; retry later",
                         {}},
               last);
        if (last) return;
        keep = true;
      } else {
        ++busy_;
        keep = ProcessOne(c, f.skip, f.total(), last);
        --busy_;
      }
      if (c.closed) return;
      c.in.erase(0, f.total());
      ++c.served;
      c.request_started = c.head_seen = c.continue_sent = false;
      if (!keep || last) {
        Close(c, true);
        return;
      }
      handled_any = true;
    }
    if (c.peer_closed) {
      // Half-closed with nothing complete left: nothing more can come.
      Close(c, false);
      return;
    }
    // TLS may hold decrypted bytes that epoll cannot see.
    if (handled_any && c.ssl && SSL_pending(c.ssl) > 0) continue;
    break;
  }
  if (!c.request_started) c.deadline = Clock::now() + options_.keep_alive_timeout;
  Rearm(c);
}

bool HttpServer::ProcessOne(Connection& c, std::size_t skip, std::size_t total, bool last) {
  RequestStream stream(c, std::string_view(c.in).substr(skip, total - skip),
                       options_.write_timeout);
  bool connection_closed = false;
  const bool ok = engine_->process_request(
      stream, last, connection_closed, [](httplib::Request& req) {
        // Ranges are for files: an API answer (or its error) is never cut
        // into multipart/byteranges.
        req.ranges.clear();
        // 100 Continue was sent by the front end when the body was awaited.
        req.headers.erase("Expect");
        // Absolute form ("GET http://host/path HTTP/1.1"), RFC 9112 §3.2.2.
        for (std::string_view scheme : {"http://", "https://"}) {
          if (req.path.size() >= scheme.size() &&
              std::equal(scheme.begin(), scheme.end(), req.path.begin(), [](char a, char b) {
                return a == std::tolower(static_cast<unsigned char>(b));
              })) {
            const std::size_t slash = req.path.find('/', scheme.size());
            req.path = slash == std::string::npos ? "/" : req.path.substr(slash);
            break;
          }
        }
      });
  return stream.Finish() && ok && !connection_closed;
}

void HttpServer::Rearm(Connection& c, bool want_write) {
  epoll_event event{};
  event.events = (want_write ? EPOLLOUT : EPOLLIN) | EPOLLONESHOT;
  event.data.u64 = c.id;
  if (::epoll_ctl(epoll_fd_, EPOLL_CTL_MOD, c.fd, &event) != 0) Close(c, false);
}

void HttpServer::Refuse(Connection& c, const HttpError& error, bool close) {
  const std::string body = ErrorJson(error).dump(-1, ' ', false,
                                                 nlohmann::json::error_handler_t::replace);
  std::string response = "HTTP/1.1 " + std::to_string(error.http_status) + " " +
                         ReasonPhrase(error.http_status) +
                         "\r\nContent-Type: application/json\r\nContent-Length: " +
                         std::to_string(body.size()) +
                         "\r\nCache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\n";
  if (error.http_status == 503) response += "Retry-After: 1\r\n";
  response += close ? "Connection: close\r\n\r\n" : "\r\n";
  response += body;
  const bool sent = c.SendAll(c.out + response, options_.write_timeout);
  c.out.clear();
  if (close || !sent) Close(c, sent);
}

void HttpServer::Close(Connection& c, bool graceful) {
  if (c.closed) return;
  if (graceful && !c.lingering && !stop_requested_.load()) {
    // Shut our side and keep reading briefly: closing with unread input
    // would reset the connection and could destroy the answer just sent.
    if (c.ssl) SSL_shutdown(c.ssl);
    ::shutdown(c.fd, SHUT_WR);
    c.lingering = true;
    c.in.clear();
    c.deadline = Clock::now() + kLinger;
    Rearm(c);
    return;
  }
  c.closed = true;
  ::epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, c.fd, nullptr);
  if (c.ssl) {
    SSL_free(c.ssl);
    c.ssl = nullptr;
  }
  ::close(c.fd);
  std::lock_guard lock(connections_mutex_);
  connections_.erase(c.id);
}

}  // namespace fesbench::server::http
