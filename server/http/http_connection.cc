#include "server/http/http_server_internal.h"

// HttpServer's connections: accepting them, reading and framing requests,
// answering one at a time in order, refusing and closing.

namespace fesbench::server::http {

void HttpServer::Accept() {
  for (std::size_t k = 0; k < kAcceptBatch; ++k) {
    sockaddr_storage peer{};
    socklen_t peer_length = sizeof peer;
    const int fd = ::accept4(listen_fd_, reinterpret_cast<sockaddr*>(&peer), &peer_length,
                             SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) {
      if (errno == EINTR || errno == ECONNABORTED) continue;
      if ((errno == EMFILE || errno == ENFILE) && EvictOne(nullptr, 0)) continue;
      break;  // EAGAIN: all taken
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
    // Idle (not request_started) until its first byte, as a kept-alive
    // connection between requests; a crowd of them is made room for, not
    // waited out (EvictOne).
    c->deadline = Clock::now() + options_.keep_alive_timeout;
    std::size_t open = 0, from_address = 0;
    {
      std::lock_guard lock(connections_mutex_);
      c->id = next_id_++;
      connections_.emplace(c->id, c);
      open = connections_.size();
      from_address = ++per_address_[c->remote_ip];
    }
    // Never refuse a connection (it may carry an e-stop): make room instead.
    bool no_room = false;
    if (from_address > options_.max_connections_per_address) {
      no_room = !EvictOne(&c->remote_ip, c->id);
    } else if (open > options_.max_open_connections) {
      no_room = !EvictOne(nullptr, c->id);
    }
    std::lock_guard lock(c->mutex);
    if (c->closed) continue;  // made room for another worker's new connection
    c->urgent_only = no_room;
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
  // One worker accepts at a time (the listening socket is one-shot) and
  // gives the socket back after a batch: a flood of connections then queues
  // behind the requests already waiting instead of holding every worker in
  // accept (docs/SAFETY.md, "The e-stop under load").
  epoll_event listen_event{};
  listen_event.events = EPOLLIN | EPOLLONESHOT;
  listen_event.data.u64 = 0;
  ::epoll_ctl(epoll_fd_, EPOLL_CTL_MOD, listen_fd_, &listen_event);
}

bool HttpServer::EvictOne(const std::string* address, std::uint64_t except) {
  std::vector<std::shared_ptr<Connection>> candidates;  // oldest first
  {
    std::lock_guard lock(connections_mutex_);
    candidates.reserve(connections_.size());
    for (const auto& [id, c] : connections_) {
      if (id != except && (address == nullptr || c->remote_ip == *address)) candidates.push_back(c);
    }
  }
  // First an answered (lingering) connection or an idle one with no bytes
  // waiting, then one whose bytes stopped coming, then any; never one a
  // worker is handling (its mutex is held). Bytes waiting in the kernel mean
  // a request is arriving: a new connection whose head (an e-stop, say) has
  // not been read yet is not idle, however many came after it.
  for (const int pass : {0, 1, 2}) {
    for (const auto& c : candidates) {
      std::unique_lock lock(c->mutex, std::try_to_lock);
      if (!lock.owns_lock() || c->closed) continue;
      // A connection seen with bytes waiting stays "arriving" until a worker
      // reads them, so a crowd costs one look each, not one per accept.
      if (pass < 2 && !c->arriving && !c->lingering) c->arriving = c->BytesWaiting();
      const bool quiet = pass == 2 || !c->arriving;
      if (pass == 0 && !c->lingering && (c->request_started || !quiet)) continue;
      if (pass == 1 && !c->lingering && !quiet) continue;
      Close(*c, false);
      return true;
    }
  }
  return false;
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
  c->arriving = false;  // what was waiting is read now
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
          c->request_started = true;  // the handshake counts against the head's deadline
          c->deadline = Clock::now() + options_.head_timeout;
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

namespace {

// The head of an upload as the parser is to see it: the body is in a file,
// so Content-Length is 0 (and Expect is gone: 100 Continue was ours to send).
std::string HeadWithoutBody(std::string_view head) {
  std::string out;
  out.reserve(head.size());
  while (!head.empty()) {
    const std::size_t eol = head.find("\r\n");
    const std::string_view line = head.substr(0, eol == std::string_view::npos ? head.size() : eol + 2);
    head.remove_prefix(line.size());
    if (line == "\r\n") {
      if (out.empty()) continue;  // empty lines before the request line
      out += "Content-Length: 0\r\n\r\n";
      break;
    }
    const std::string_view name = line.substr(0, line.find(':'));
    auto is = [&](std::string_view header) {
      return name.size() == header.size() &&
             std::equal(name.begin(), name.end(), header.begin(), [](char a, char b) {
               return std::tolower(static_cast<unsigned char>(a)) == b;
             });
    };
    if (!is("content-length") && !is("expect")) out += line;
  }
  return out;
}

int OpenSpoolFile(const std::string& dir) {
  int fd = ::open(dir.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
  if (fd >= 0) return fd;
  std::string path = dir + "/fesbench-upload-XXXXXX";
  fd = ::mkostemp(path.data(), O_CLOEXEC);
  if (fd >= 0) ::unlink(path.c_str());
  return fd;
}

bool WriteAll(int fd, std::string_view data) {
  while (!data.empty()) {
    const ssize_t n = ::write(fd, data.data(), data.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    data.remove_prefix(static_cast<std::size_t>(n));
  }
  return true;
}

}  // namespace

void HttpServer::HandleBytes(Connection& c) {
  FramingLimits limits;
  limits.max_head_bytes = options_.max_head_bytes;
  limits.max_headers = options_.max_headers;
  limits.max_body_bytes = options_.max_body_bytes;
  limits.max_upload_bytes = options_.max_upload_bytes;
  for (;;) {
    // Read no further than one whole request beyond a full one (pipelined
    // requests wait in the kernel until their turn), and while spooling no
    // more than a few chunks past the head at a time.
    const std::size_t read_limit =
        c.spool_fd >= 0 ? c.head_length + 4 * kReadChunk
                        : options_.max_head_bytes + options_.max_body_bytes + kReadChunk;
    const std::size_t before = c.in.size();
    if (!c.ReadAvailable(read_limit)) {
      Close(c, false);
      return;
    }
    bool progress = c.in.size() != before;
    while (!c.in.empty()) {
      if (c.spool_fd >= 0) {
        if (!SpoolBody(c)) return;
        if (c.spool_written < c.spool_expected) break;
        const UploadBody upload{c.spool_fd, c.spool_expected};
        ::lseek(c.spool_fd, 0, SEEK_SET);
        const std::string head = HeadWithoutBody(std::string_view(c.in).substr(0, c.head_length));
        if (!Answer(c, head, c.head_length, true, &upload)) return;
        progress = true;
        continue;
      }
      const Framing f = FrameRequest(c.in, limits);
      if (f.state == Framing::State::kError) {
        Refuse(c, f.error, true);
        return;
      }
      const auto now = Clock::now();
      if (!c.request_started) {
        c.request_started = true;
        c.deadline = now + options_.head_timeout;
      }
      if (!f.head_complete) break;
      if (!c.admitted && (f.upload || f.state == Framing::State::kIncomplete)) {
        // Checked on the head alone, before a byte of the body is read.
        std::string extra_headers;
        if (auto refusal = Preadmit(c, f.method, f.path, f.authorization, f.content_type,
                                    extra_headers)) {
          Refuse(c, *refusal, true, extra_headers);
          return;
        }
        c.admitted = true;
      }
      if (f.upload) {
        if (!StartSpool(c, f.skip + f.head_bytes, f.body_bytes, f.expect_continue)) return;
        continue;
      }
      if (f.state == Framing::State::kIncomplete) {
        if (!c.head_seen) {
          c.head_seen = true;
          c.deadline = now + options_.request_timeout;
        }
        if (f.expect_continue && !c.continue_sent) {
          c.continue_sent = true;
          if (!c.SendAll("HTTP/1.1 100 Continue\r\n\r\n", options_.write_timeout)) {
            Close(c, false);
            return;
          }
        }
        break;
      }
      const std::string_view request = std::string_view(c.in).substr(f.skip, f.total() - f.skip);
      if (!Answer(c, request, f.total(), f.keep_alive, nullptr)) return;
      progress = true;
    }
    if (c.peer_closed) {
      // Half-closed with nothing complete left: nothing more can come.
      Close(c, false);
      return;
    }
    // TLS may hold decrypted bytes that epoll cannot see.
    if (progress && c.ssl && SSL_pending(c.ssl) > 0) continue;
    break;
  }
  if (!c.request_started) c.deadline = Clock::now() + options_.keep_alive_timeout;
  Rearm(c);
}

bool HttpServer::Answer(Connection& c, std::string_view request, std::size_t consumed,
                        bool keep_alive, const UploadBody* upload) {
  // The request line: "METHOD SP target SP version" (framed already).
  const std::size_t sp1 = request.find(' ');
  const std::string_view method = request.substr(0, sp1);
  const std::string_view target = request.substr(sp1 + 1, request.find(' ', sp1 + 1) - sp1 - 1);
  const bool urgent = IsUrgent(method, target.substr(0, target.find('?')));
  const bool more_allowed = c.served + 1 < options_.keep_alive_max_count &&
                            !stop_requested_.load() && !(c.peer_closed && c.in.size() == consumed);
  const bool last = !keep_alive || !more_allowed;
  bool keep = true;
  if (!urgent && (c.urgent_only || busy_.load() >= workers_ - kUrgentReserve)) {
    Refuse(c,
           HttpError{503, "unavailable",
                     c.urgent_only ? std::string("the server has no room for another connection; "
                                                 "retry later")
                                   : "the server is handling " + std::to_string(busy_.load()) +
                                         " requests; retry later",
                     {}},
           last);
    if (last || c.closed) return false;
  } else {
    ++busy_;
    keep = ProcessOne(c, request, last, upload);
    --busy_;
  }
  if (c.closed) return false;
  EndSpool(c);
  c.in.erase(0, consumed);
  ++c.served;
  c.request_started = c.head_seen = c.admitted = c.continue_sent = false;
  c.preadmission = {};
  if (!keep || last) {
    Close(c, true);
    return false;
  }
  return true;
}

std::optional<HttpError> HttpServer::Preadmit(Connection& c, std::string_view method,
                                              std::string_view path,
                                              std::string_view authorization,
                                              std::string_view content_type,
                                              std::string& extra_headers) {
  // The raw path: a target that matches no route here (percent-encoded, say)
  // is routed by the dispatcher once its body (at most max_body_bytes) is in.
  const RouteMatch match = routes_.Match(method, path);
  if (!match.route) return std::nullopt;
  const Route& route = *match.route;
  RouteAdmission admitted = AdmitTo(route, method, path, authorization, c.remote_ip);
  if (admitted.refusal) {
    for (const auto& [name, value] : admitted.headers) extra_headers += name + ": " + value + "\r\n";
    return admitted.refusal;
  }
  if (route.json_body && !IsJsonContentType(content_type)) {
    return HttpError{415, "unsupported_media_type",
                     "the request body must be JSON (Content-Type: application/json)", {}};
  }
  c.preadmission = {&route, std::move(admitted.user)};
  return std::nullopt;
}

bool HttpServer::StartSpool(Connection& c, std::size_t head_length, std::size_t body_bytes,
                            bool expect_continue) {
  std::size_t held = spooled_bytes_.load();
  do {
    if (held + body_bytes > options_.max_spooled_bytes) {
      Refuse(c,
             HttpError{503, "unavailable",
                       "the server is receiving " + std::to_string(held >> 20) +
                           " MiB of other uploads; retry later",
                       {}},
             true);
      return false;
    }
  } while (!spooled_bytes_.compare_exchange_weak(held, held + body_bytes));
  c.spool_expected = body_bytes;  // reserved: EndSpool gives it back
  c.spool_written = 0;
  c.head_length = head_length;
  c.spool_fd = OpenSpoolFile(options_.upload_dir);
  if (c.spool_fd < 0) {
    const int error = errno;
    std::cerr << "fesbench-server: cannot spool an upload in " << options_.upload_dir << ": "
              << std::strerror(error) << std::endl;
    EndSpool(c);
    Refuse(c, HttpError{503, "unavailable", "the server cannot store uploads now; retry later", {}},
           true);
    return false;
  }
  const auto now = Clock::now();
  c.head_seen = true;
  c.spool_deadline =
      now + options_.request_timeout + std::chrono::seconds(body_bytes >> 20);
  c.deadline = std::min(c.spool_deadline, now + options_.request_timeout);
  if (expect_continue && !c.continue_sent) {
    c.continue_sent = true;
    if (!c.SendAll("HTTP/1.1 100 Continue\r\n\r\n", options_.write_timeout)) {
      Close(c, false);
      return false;
    }
  }
  return true;
}

bool HttpServer::SpoolBody(Connection& c) {
  const std::size_t take =
      std::min(c.in.size() - c.head_length, c.spool_expected - c.spool_written);
  if (take == 0) return true;
  if (!WriteAll(c.spool_fd, std::string_view(c.in).substr(c.head_length, take))) {
    const int error = errno;
    std::cerr << "fesbench-server: cannot spool an upload: " << std::strerror(error) << std::endl;
    Refuse(c, HttpError{503, "unavailable", "the server cannot store uploads now; retry later", {}},
           true);
    return false;
  }
  c.in.erase(c.head_length, take);
  c.spool_written += take;
  // Progress: the body may stall request_timeout again, within its whole.
  c.deadline = std::min(c.spool_deadline, Clock::now() + options_.request_timeout);
  return true;
}

void HttpServer::EndSpool(Connection& c) {
  if (c.spool_fd >= 0) ::close(c.spool_fd);
  if (c.spool_fd >= 0 || c.spool_expected > 0) spooled_bytes_ -= c.spool_expected;
  c.spool_fd = -1;
  c.head_length = c.spool_expected = c.spool_written = 0;
}

bool HttpServer::ProcessOne(Connection& c, std::string_view request, bool last,
                            const UploadBody* upload) {
  Request req;
  req.remote_addr = c.remote_ip;
  req.remote_port = c.remote_port;
  auto fresh_response = [] {
    Response res;
    res.set_header("Cache-Control", "no-store");
    res.set_header("X-Content-Type-Options", "nosniff");
    return res;
  };
  Response res = fresh_response();
  bool keep = true;
  if (auto refusal = ParseRequest(request, req)) {
    WriteError(res, *refusal);
  } else {
    const std::string connection = req.get_header_value("Connection");
    keep = connection != "close" && (req.version != "HTTP/1.0" || connection == "Keep-Alive");
    if (req.has_header("Range") && !IsValidRange(req.get_header_value("Range"))) {
      res.status = 416;  // FinishResponse gives it its JSON body
    } else {
      try {
        Dispatch(req, res, upload, std::move(c.preadmission));
      } catch (...) {
        std::cerr << "fesbench-server: internal error on " << req.method << " "
                  << req.path.substr(0, 120) << std::endl;
        res = fresh_response();
        WriteError(res, HttpError{500, "internal", "internal server error", {}});
      }
      if (res.status == -1) res.status = 200;
    }
  }
  const KeepAliveTerms terms{
      std::chrono::duration_cast<std::chrono::seconds>(options_.keep_alive_timeout),
      options_.keep_alive_max_count};
  c.out += FinishResponse(req, res, last, terms);
  if (res.events && req.method != "HEAD") return SendEventStream(c, res) && keep;
  if (req.method != "HEAD") c.out += res.body;
  return c.Flush(options_.write_timeout) && keep;
}

bool HttpServer::SendEventStream(Connection& c, Response& res) {
  bool ok = true;
  bool open = true;
  EventSink sink;
  // The head waits in `out` for the first chunk, so both leave together.
  sink.write = [&](std::string_view data) {
    if (!ok) return false;
    open = !data.empty();
    if (!data.empty()) {
      c.out += EventChunk(data);
      ok = c.Flush(options_.write_timeout);
    }
    return ok;
  };
  sink.done = [&] {
    if (!ok) return;
    open = false;
    c.out += kLastChunk;
    ok = c.Flush(options_.write_timeout);
  };
  while (open && !stop_requested_.load()) {
    if (!res.events(sink) || !ok) return false;
  }
  return c.Flush(options_.write_timeout);
}

void HttpServer::Rearm(Connection& c, bool want_write) {
  epoll_event event{};
  event.events = (want_write ? EPOLLOUT : EPOLLIN) | EPOLLONESHOT;
  event.data.u64 = c.id;
  if (::epoll_ctl(epoll_fd_, EPOLL_CTL_MOD, c.fd, &event) != 0) Close(c, false);
}

void HttpServer::Refuse(Connection& c, const HttpError& error, bool close,
                        std::string_view extra_headers) {
  const std::string body = ErrorJson(error).dump(-1, ' ', false,
                                                 nlohmann::json::error_handler_t::replace);
  std::string response = "HTTP/1.1 " + std::to_string(error.http_status) + " " +
                         ReasonPhrase(error.http_status) +
                         "\r\nContent-Type: application/json\r\nContent-Length: " +
                         std::to_string(body.size()) +
                         "\r\nCache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\n";
  if (error.http_status == 503) response += "Retry-After: 1\r\n";
  response += extra_headers;
  response += close ? "Connection: close\r\n\r\n" : "\r\n";
  response += body;
  const bool sent = c.SendAll(c.out + response, options_.write_timeout);
  c.out.clear();
  if (close || !sent) Close(c, sent);
}

void HttpServer::Close(Connection& c, bool graceful) {
  if (c.closed) return;
  EndSpool(c);
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
  if (auto it = per_address_.find(c.remote_ip); it != per_address_.end() && --it->second == 0) {
    per_address_.erase(it);
  }
}

}  // namespace fesbench::server::http
