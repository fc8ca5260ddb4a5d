#include "server/http/http_server.h"

#include <arpa/inet.h>
#include <httplib.h>
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
#include <cstring>
#include <exception>
#include <iostream>
#include <thread>

#include "server/http/errors.h"
#include "server/http/json_fields.h"
#include "server/http/request_framing.h"
#include "storage/audit_log.h"

namespace fesbench::server::http {

namespace {

bool IsStateChanging(std::string_view method) {
  return method == "POST" || method == "PUT" || method == "DELETE" || method == "PATCH";
}

// Echo at most a short prefix of client text in messages.
std::string Clip(std::string_view text, std::size_t n = 120) {
  return text.size() <= n ? std::string(text) : std::string(text.substr(0, n)) + "…";
}

bool IsJsonContentType(std::string_view value) {
  std::string lower;
  for (char c : value.substr(0, value.find(';'))) {
    if (c != ' ' && c != '\t') lower.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(c))));
  }
  return lower == "application/json";
}

// Library-made errors (parse failures, 413, 414, …) get the same JSON form.
HttpError LibraryError(const httplib::Request& req, int status) {
  switch (status) {
    case 400:
      if (req.method == "CONNECT" || req.method == "TRACE" || req.method == "PRI") {
        return {405, "method_not_allowed", "method " + req.method + " is not supported", {}};
      }
      return {400, "bad_request", "malformed HTTP request", {}};
    case 404:
      return {404, "not_found", "no route for " + Clip(req.method) + " " + Clip(req.path), {}};
    case 413:
      return {413, "payload_too_large", "request body exceeds the server's limit", {}};
    case 414:
      return {414, "uri_too_long", "request line too long", {}};
    case 416:
      return {416, "range_not_satisfiable", "invalid Range header", {}};
    default:
      if (status >= 500) return {status, "internal", "internal server error", {}};
      return {status, "bad_request", "request refused", {}};
  }
}

}  // namespace

std::string AuditSummary(const nlohmann::json& body) {
  if (body.is_null()) return {};
  std::string text = body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  if (text.size() > 512) text = text.substr(0, 509) + "...";
  return text;
}

// ---------------------------------------------------------------------------
// The connection loop.

namespace {

using Clock = std::chrono::steady_clock;

// Two workers beyond max_connections + max_streams, for urgent routes.
constexpr std::size_t kUrgentReserve = 2;
// How long a closed connection keeps reading (and discarding) what the
// client still sends, so that the client reads our last answer instead of
// a reset.
constexpr auto kLinger = std::chrono::milliseconds(2000);
constexpr std::size_t kReadChunk = 16 * 1024;
constexpr std::size_t kWriteBuffer = 64 * 1024;

const char* ReasonPhrase(int status) {
  switch (status) {
    case 400: return "Bad Request";
    case 408: return "Request Timeout";
    case 411: return "Length Required";
    case 413: return "Payload Too Large";
    case 414: return "URI Too Long";
    case 431: return "Request Header Fields Too Large";
    case 503: return "Service Unavailable";
    default: return "Error";
  }
}

std::string AddressText(const sockaddr_storage& addr, int& port) {
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

}  // namespace

// httplib's request parser, routing and response writer, fed one buffered
// request at a time (process_request is protected: reached by subclassing).
class HttpServer::Engine : public httplib::Server {
 public:
  using httplib::Server::process_request;
  // Content providers (event streams) run only while the library believes
  // it is listening: it checks its own listening socket, which we hold.
  void SetServing(socket_t listening) { svr_sock_ = listening; }
};

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
  bool continue_sent = false;
  bool peer_closed = false;  ///< the client half-closed (FIN read).
  bool lingering = false;    ///< answered and shut down; discarding input.
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

  // The client has closed its side (a FIN is waiting to be read).
  bool PeerGone() const {
    char byte;
    const ssize_t n = ::recv(fd, &byte, 1, MSG_PEEK | MSG_DONTWAIT);
    return n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR);
  }
};

namespace {

// One buffered request as httplib's Stream: reads come from memory, writes
// go to the connection (the head joined with what follows it).
class RequestStream final : public httplib::Stream {
 public:
  RequestStream(HttpServer::Connection& c, std::string_view request,
                std::chrono::milliseconds write_timeout)
      : c_(c), request_(request), write_timeout_(write_timeout) {}

  bool is_readable() const override { return pos_ < request_.size(); }
  bool is_writable() const override {
    // Asked by content providers (event streams): report a departed client
    // so its worker is freed.
    return !failed_ && c_.Flush(write_timeout_) && !c_.PeerGone() &&
           c_.WaitFor(POLLOUT, write_timeout_);
  }
  ssize_t read(char* ptr, size_t size) override {
    const std::size_t n = std::min(size, request_.size() - pos_);
    std::memcpy(ptr, request_.data() + pos_, n);
    pos_ += n;
    return static_cast<ssize_t>(n);
  }
  ssize_t write(const char* ptr, size_t size) override {
    if (failed_) return -1;
    c_.out.append(ptr, size);
    // The library writes the response head first: keep it until the body
    // (or the end) so both leave in one segment; send every later write at
    // once (event-stream chunks must not wait).
    if ((writes_++ > 0 || c_.out.size() >= kWriteBuffer) && !c_.Flush(write_timeout_)) {
      failed_ = true;
      return -1;
    }
    return static_cast<ssize_t>(size);
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    ip = c_.remote_ip;
    port = c_.remote_port;
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    ip = c_.local_ip;
    port = c_.local_port;
  }
  // The library's only server-side use is an FD_SETSIZE guard for its own
  // select()-based socket reads, which this stream does not do.
  socket_t socket() const override { return -1; }

  bool Finish() { return !failed_ && c_.Flush(write_timeout_); }

 private:
  HttpServer::Connection& c_;
  std::string_view request_;
  std::size_t pos_ = 0;
  std::size_t writes_ = 0;
  std::chrono::milliseconds write_timeout_;
  mutable bool failed_ = false;
};

}  // namespace

HttpServer::HttpServer(HttpServerOptions options, RouteTable routes, Authenticator& auth,
                       storage::Database& db, StreamSlots& slots)
    : options_(std::move(options)),
      routes_(std::move(routes)),
      auth_(auth),
      db_(db),
      slots_(slots) {
  if (!options_.web_root.empty()) static_files_.emplace(options_.web_root);
}

HttpServer::~HttpServer() {
  Stop();
  if (listen_fd_ >= 0) ::close(listen_fd_);
  if (epoll_fd_ >= 0) ::close(epoll_fd_);
  if (wake_fd_ >= 0) ::close(wake_fd_);
  if (tls_) SSL_CTX_free(tls_);
}

api::Result<int> HttpServer::Bind() {
  if (!options_.tls_cert_path.empty() || !options_.tls_key_path.empty()) {
    if (options_.tls_cert_path.empty() || options_.tls_key_path.empty()) {
      return api::Status::InvalidArgument("TLS needs both a certificate and a key", "tls-cert");
    }
    tls_ = SSL_CTX_new(TLS_server_method());
    if (!tls_ || SSL_CTX_set_min_proto_version(tls_, TLS1_2_VERSION) != 1 ||
        SSL_CTX_use_certificate_chain_file(tls_, options_.tls_cert_path.c_str()) != 1 ||
        SSL_CTX_use_PrivateKey_file(tls_, options_.tls_key_path.c_str(), SSL_FILETYPE_PEM) != 1 ||
        SSL_CTX_check_private_key(tls_) != 1) {
      return api::Status::InvalidArgument("cannot load the TLS certificate or key", "tls-cert");
    }
    SSL_CTX_set_options(tls_, SSL_OP_NO_COMPRESSION | SSL_OP_NO_RENEGOTIATION);
    SSL_CTX_set_mode(tls_, SSL_MODE_ENABLE_PARTIAL_WRITE | SSL_MODE_ACCEPT_MOVING_WRITE_BUFFER);
  }

  engine_ = std::make_unique<Engine>();
  Engine& svr = *engine_;
  svr.set_payload_max_length(std::max(options_.max_body_bytes, options_.max_upload_bytes));
  svr.set_keep_alive_timeout(
      std::chrono::duration_cast<std::chrono::seconds>(options_.keep_alive_timeout).count());
  svr.set_keep_alive_max_count(options_.keep_alive_max_count);
  svr.set_default_headers({{"Cache-Control", "no-store"}, {"X-Content-Type-Options", "nosniff"}});

  auto dispatch = [this](const httplib::Request& req, httplib::Response& res) {
    Dispatch(req, res);
  };
  svr.Get(".*", dispatch);
  svr.Post(".*", dispatch);
  svr.Put(".*", dispatch);
  svr.Patch(".*", dispatch);
  svr.Delete(".*", dispatch);
  svr.Options(".*", dispatch);

  svr.set_error_handler(httplib::Server::HandlerWithResponse(
      [](const httplib::Request& req, httplib::Response& res) {
        if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
        WriteError(res, LibraryError(req, res.status));
        return httplib::Server::HandlerResponse::Handled;
      }));
  svr.set_exception_handler(
      [](const httplib::Request& req, httplib::Response& res, std::exception_ptr ep) {
        std::string what = "unknown exception";
        try {
          if (ep) std::rethrow_exception(ep);
        } catch (const std::exception& e) {
          what = e.what();
        } catch (...) {
        }
        std::cerr << "fesbench-server: internal error on " << req.method << " " << Clip(req.path)
                  << ": " << what << std::endl;
        WriteError(res, HttpError{500, "internal", "internal server error", {}});
      });

  // The listening socket: SO_REUSEADDR (restart while old connections sit
  // in TIME_WAIT) but not SO_REUSEPORT, so a port in use is refused.
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
  addrinfo* found = nullptr;
  const std::string service = std::to_string(options_.port);
  const std::string where = options_.bind_address + ":" + std::to_string(options_.port);
  if (::getaddrinfo(options_.bind_address.c_str(), service.c_str(), &hints, &found) != 0 ||
      !found) {
    return api::Status::Unavailable("cannot bind " + where + ": unknown address");
  }
  int error = 0;
  for (addrinfo* ai = found; ai && listen_fd_ < 0; ai = ai->ai_next) {
    const int fd = ::socket(ai->ai_family, ai->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC,
                            ai->ai_protocol);
    if (fd < 0) {
      error = errno;
      continue;
    }
    const int yes = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
    if (::bind(fd, ai->ai_addr, ai->ai_addrlen) != 0 || ::listen(fd, 1024) != 0) {
      error = errno;
      ::close(fd);
      continue;
    }
    listen_fd_ = fd;
  }
  ::freeaddrinfo(found);
  if (listen_fd_ < 0) {
    if (error == EADDRINUSE) {
      return api::Status::Unavailable("cannot bind " + where +
                                      ": address in use (is another server running there?)");
    }
    return api::Status::Unavailable("cannot bind " + where + ": " + std::strerror(error));
  }
  sockaddr_storage bound{};
  socklen_t length = sizeof bound;
  ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&bound), &length);
  int port = 0;
  AddressText(bound, port);

  epoll_fd_ = ::epoll_create1(EPOLL_CLOEXEC);
  wake_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (epoll_fd_ < 0 || wake_fd_ < 0) return api::Status::Unavailable("cannot create epoll");
  epoll_event listen_event{};
  listen_event.events = EPOLLIN;
  listen_event.data.u64 = 0;  // connection ids start at 1
  epoll_event wake_event{};
  wake_event.events = EPOLLIN;
  wake_event.data.u64 = UINT64_MAX;
  if (::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, listen_fd_, &listen_event) != 0 ||
      ::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, wake_fd_, &wake_event) != 0) {
    return api::Status::Unavailable("cannot watch the listening socket");
  }
  workers_ = options_.max_connections + options_.max_streams + kUrgentReserve;
  return port;
}

bool HttpServer::Run() {
  if (!engine_ || listen_fd_ < 0) return false;
  {
    std::lock_guard lock(run_mutex_);
    if (stop_requested_.load()) return true;
    running_.store(true);
  }
  engine_->SetServing(listen_fd_);
  std::vector<std::thread> threads;
  threads.reserve(workers_ + 1);
  for (std::size_t i = 0; i < workers_; ++i) threads.emplace_back([this] { WorkerLoop(); });
  threads.emplace_back([this] { SweepLoop(); });
  for (auto& t : threads) t.join();

  std::vector<std::shared_ptr<Connection>> left;
  {
    std::lock_guard lock(connections_mutex_);
    for (auto& [id, c] : connections_) left.push_back(c);
  }
  for (auto& c : left) {
    std::lock_guard lock(c->mutex);
    Close(*c, false);
  }
  {
    std::lock_guard lock(run_mutex_);
    running_.store(false);
  }
  run_cv_.notify_all();
  return true;
}

void HttpServer::Stop() {
  stop_requested_.store(true);
  slots_.Shutdown();
  if (engine_) engine_->SetServing(INVALID_SOCKET);  // ends event streams
  if (wake_fd_ >= 0) {
    const std::uint64_t one = 1;
    [[maybe_unused]] auto n = ::write(wake_fd_, &one, sizeof one);
  }
  std::unique_lock lock(run_mutex_);
  run_cv_.wait(lock, [this] { return !running_.load(); });
}

bool HttpServer::IsUrgent(std::string_view method, std::string_view path) const {
  return std::any_of(options_.urgent_routes.begin(), options_.urgent_routes.end(),
                     [&](const std::string& route) {
                       return route.size() == method.size() + 1 + path.size() &&
                              route.compare(0, method.size(), method) == 0 &&
                              route[method.size()] == ' ' &&
                              route.compare(method.size() + 1, path.size(), path) == 0;
                     });
}

void HttpServer::WorkerLoop() {
  for (;;) {
    epoll_event event{};
    const int n = ::epoll_wait(epoll_fd_, &event, 1, -1);
    if (stop_requested_.load()) return;
    if (n <= 0) continue;
    if (event.data.u64 == 0) {
      Accept();
    } else if (event.data.u64 != UINT64_MAX) {
      Serve(event.data.u64);
    }
  }
}

void HttpServer::SweepLoop() {
  while (!stop_requested_.load()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    std::vector<std::shared_ptr<Connection>> all;
    {
      std::lock_guard lock(connections_mutex_);
      all.reserve(connections_.size());
      for (auto& [id, c] : connections_) all.push_back(c);
    }
    const auto now = Clock::now();
    for (auto& c : all) {
      std::unique_lock lock(c->mutex, std::try_to_lock);
      if (!lock.owns_lock() || c->closed || now < c->deadline) continue;  // busy: a worker has it
      if (c->lingering) {
        Close(*c, false);
      } else if (c->request_started) {
        Refuse(*c,
               HttpError{408, "request_timeout",
                         "the request was not complete within " +
                             std::to_string(options_.request_timeout.count()) + " ms",
                         {}},
               true);
      } else {
        Close(*c, false);  // idle keep-alive connection
      }
    }
  }
}

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

void HttpServer::AuditRefusal(const RequestContext& ctx, int status, const std::string& code) {
  if (!ctx.user || !IsStateChanging(ctx.req.method)) return;
  storage::AuditLog log(db_);
  auto appended = log.Append({ctx.user->id, ctx.user->name, ctx.req.method + " " + Clip(ctx.req.path, 200),
                              Clip(ctx.req.path, 200), AuditSummary(ctx.body),
                              std::to_string(status) + " " + code});
  if (!appended.ok()) {
    std::cerr << "fesbench-server: audit log: " << appended.status().ToString() << std::endl;
  }
}

void HttpServer::Dispatch(const httplib::Request& req, httplib::Response& res) {
  const RouteMatch match = routes_.Match(req.method, req.path);
  if (!match.route) {
    if (match.allowed_methods.empty() && static_files_ && static_files_->Serve(req, res)) return;
    if (match.allowed_methods.empty()) {
      WriteError(res, HttpError{404, "not_found",
                                "no route for " + Clip(req.method) + " " + Clip(req.path), {}});
    } else {
      std::string allow;
      for (const auto& m : match.allowed_methods) allow += (allow.empty() ? "" : ", ") + m;
      res.set_header("Allow", allow);
      WriteError(res, HttpError{405, "method_not_allowed",
                                "method " + Clip(req.method) + " not allowed here (allowed: " +
                                    allow + ")",
                                {}});
    }
    return;
  }
  const Route& route = *match.route;
  RequestContext ctx{req, res, match.path, std::nullopt, nullptr, false};
  auto refuse = [&](const HttpError& error) {
    WriteError(res, error);
    AuditRefusal(ctx, error.http_status, error.code);
  };
  try {
    if (route.roles != 0) {
      // 401, 403 and a slowed-down burst (429) are audited by the Authenticator.
      Admission admitted =
          auth_.Admit(req.get_header_value("Authorization"), req.remote_addr, route.roles,
                      req.method + " " + Clip(req.path, 200), Clip(req.path, 200));
      if (!admitted.user) {
        if (admitted.retry_after_s > 0) {
          res.set_header("Retry-After", std::to_string(admitted.retry_after_s));
          WriteError(res, HttpError{429, "too_many_requests", admitted.status.message(), {}});
        } else {
          if (admitted.status.code() == api::ErrorCode::kUnauthenticated) {
            res.set_header("WWW-Authenticate", "Bearer");
          }
          WriteError(res, admitted.status);
        }
        return;
      }
      ctx.user = std::move(*admitted.user);
    }
    if (route.json_body && !IsJsonContentType(req.get_header_value("Content-Type"))) {
      refuse(HttpError{415, "unsupported_media_type",
                       "the request body must be JSON (Content-Type: application/json)", {}});
      return;
    }
    for (const auto& [name, value] : req.params) {
      const bool known = std::any_of(route.query.begin(), route.query.end(),
                                     [&](const QueryParam& q) { return q.name == name; });
      if (!known) {
        refuse(ToHttpError(api::Status::InvalidArgument("unknown query parameter", Clip(name, 64))));
        return;
      }
    }
    if (route.json_body) {
      auto body = ParseJsonObject(req.body);
      if (!body.ok()) {
        refuse(ToHttpError(body.status()));
        return;
      }
      ctx.body = std::move(*body);
    } else if (!req.body.empty() && !route.raw_body) {
      refuse(ToHttpError(api::Status::InvalidArgument("this request takes no body")));
      return;
    }

    auto reply = route.handler(ctx);
    if (!reply.ok()) {
      if (reply.status().code() == api::ErrorCode::kInternal ||
          reply.status().code() == api::ErrorCode::kDataLoss) {
        std::cerr << "fesbench-server: " << req.method << " " << Clip(req.path) << ": "
                  << reply.status().ToString() << std::endl;
      }
      if (ctx.audited) {
        WriteError(res, reply.status());
      } else {
        refuse(ToHttpError(reply.status()));
      }
      return;
    }
    if (!reply->raw) WriteJson(res, reply->status, reply->body);
    if (!ctx.audited && ctx.user && IsStateChanging(req.method)) {
      storage::AuditLog log(db_);
      auto appended =
          log.Append({ctx.user->id, ctx.user->name, req.method + " " + Clip(req.path, 200),
                      Clip(req.path, 200), AuditSummary(ctx.body), std::to_string(reply->status)});
      if (!appended.ok()) {
        std::cerr << "fesbench-server: audit log: " << appended.status().ToString() << std::endl;
      }
    }
  } catch (const nlohmann::json::exception& e) {
    // A JSON value of the wrong type or range that a handler read without
    // JsonFields: the client's bytes, so a 400 (and audited), never a 500.
    std::string what = e.what();
    if (const auto close = what.find("] "); what.starts_with("[json.exception") &&
                                            close != std::string::npos) {
      what = what.substr(close + 2);
    }
    refuse(ToHttpError(api::Status::InvalidArgument("invalid value in the request: " + Clip(what),
                                                    ctx.body.is_null() ? "" : "body")));
  } catch (const std::exception& e) {
    std::cerr << "fesbench-server: internal error on " << req.method << " " << Clip(req.path)
              << ": " << e.what() << std::endl;
    WriteError(res, HttpError{500, "internal", "internal server error", {}});
  }
}

}  // namespace fesbench::server::http
