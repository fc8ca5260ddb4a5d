#include "server/http/http_server.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <poll.h>
#include <sys/epoll.h>
#include <sys/resource.h>
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
#include "server/http/http_server_internal.h"
#include "storage/audit_log.h"

namespace fesbench::server::http {

namespace {

constexpr const char* kTls12Ciphers =
    "ECDHE-ECDSA-AES128-GCM-SHA256:ECDHE-RSA-AES128-GCM-SHA256:ECDHE-ECDSA-AES256-GCM-SHA384:"
    "ECDHE-RSA-AES256-GCM-SHA384:ECDHE-ECDSA-CHACHA20-POLY1305:ECDHE-RSA-CHACHA20-POLY1305";
constexpr const char* kTls13Ciphers =
    "TLS_AES_128_GCM_SHA256:TLS_AES_256_GCM_SHA384:TLS_CHACHA20_POLY1305_SHA256";

bool IsStateChanging(std::string_view method) {
  return method == "POST" || method == "PUT" || method == "DELETE" || method == "PATCH";
}

// Echo at most a short prefix of client text in messages.
std::string Clip(std::string_view text, std::size_t n = 120) {
  return text.size() <= n ? std::string(text) : std::string(text.substr(0, n)) + "…";
}

}  // namespace

std::string AuditSummary(const nlohmann::json& body) {
  if (body.is_null()) return {};
  std::string text = body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  if (text.size() > 512) text = text.substr(0, 509) + "...";
  return text;
}

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
    // Forward-secret AEAD suites only (TLS 1.2: ECDHE with AES-GCM or
    // ChaCha20-Poly1305; TLS 1.3's suites all are), server's order.
    if (SSL_CTX_set_cipher_list(tls_, kTls12Ciphers) != 1 ||
        SSL_CTX_set_ciphersuites(tls_, kTls13Ciphers) != 1) {
      return api::Status::InvalidArgument("cannot set the TLS cipher suites", "tls-cert");
    }
    SSL_CTX_set_options(tls_, SSL_OP_NO_COMPRESSION | SSL_OP_NO_RENEGOTIATION |
                                  SSL_OP_CIPHER_SERVER_PREFERENCE);
    SSL_CTX_set_mode(tls_, SSL_MODE_ENABLE_PARTIAL_WRITE | SSL_MODE_ACCEPT_MOVING_WRITE_BUFFER);
  }

  // Room for every connection the caps allow, and then some, before accept
  // can fail for want of descriptors (the soft limit is often 1,024).
  if (rlimit files{}; ::getrlimit(RLIMIT_NOFILE, &files) == 0) {
    const rlim_t wanted = static_cast<rlim_t>(2 * options_.max_open_connections + 1024);
    if (files.rlim_cur != RLIM_INFINITY && files.rlim_cur < wanted) {
      files.rlim_cur = files.rlim_max == RLIM_INFINITY ? wanted : std::min(wanted, files.rlim_max);
      ::setrlimit(RLIMIT_NOFILE, &files);
    }
  }
  if (options_.upload_dir.empty()) {
    const char* tmp = std::getenv("TMPDIR");
    options_.upload_dir = tmp != nullptr && *tmp != '\0' ? tmp : "/tmp";
  }
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
  listen_event.events = EPOLLIN | EPOLLONESHOT;  // re-armed by Accept
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
  if (listen_fd_ < 0) return false;
  {
    std::lock_guard lock(run_mutex_);
    if (stop_requested_.load()) return true;
    running_.store(true);
  }
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
        const std::string message =
            !c->head_seen
                ? "the request head was not complete within " +
                      std::to_string(options_.head_timeout.count()) + " ms"
                : c->spool_fd >= 0
                      ? "the upload stalled or came too slowly (" +
                            std::to_string(c->spool_written) + " of " +
                            std::to_string(c->spool_expected) + " bytes arrived)"
                      : "the request body was not complete within " +
                            std::to_string(options_.request_timeout.count()) + " ms";
        Refuse(*c, HttpError{408, "request_timeout", message, {}}, true);
      } else {
        Close(*c, false);  // idle keep-alive connection
      }
    }
  }
}

void HttpServer::WriteAudit(const RequestContext& ctx, const std::string& outcome) {
  if (!ctx.user || !IsStateChanging(ctx.req.method)) return;
  storage::AuditLog log(db_);
  auto appended = log.Append({ctx.user->id, ctx.user->name, ctx.req.method + " " + Clip(ctx.req.path, 200),
                              Clip(ctx.req.path, 200), AuditSummary(ctx.body), outcome});
  if (!appended.ok()) {
    std::cerr << "fesbench-server: audit log: " << appended.status().ToString() << std::endl;
  }
}

HttpServer::RouteAdmission HttpServer::AdmitTo(const Route& route, std::string_view method,
                                               std::string_view path,
                                               std::string_view authorization,
                                               const std::string& address) {
  RouteAdmission out;
  if (!route.permission) return out;
  // 401, 403 and a slowed-down burst (429) are audited by the Authenticator.
  const std::string where = Clip(path, 200);
  Admission admitted = auth_.Admit(authorization, address, *route.permission,
                                   std::string(method) + " " + where, where);
  if (admitted.user) {
    out.user = std::move(*admitted.user);
  } else if (admitted.retry_after_s > 0) {
    out.headers.emplace_back("Retry-After", std::to_string(admitted.retry_after_s));
    out.refusal = HttpError{429, "too_many_requests", admitted.status.message(), {}};
  } else {
    if (admitted.status.code() == api::ErrorCode::kUnauthenticated) {
      out.headers.emplace_back("WWW-Authenticate", "Bearer");
    }
    out.refusal = ToHttpError(admitted.status);
  }
  return out;
}

namespace {

// 404, or 405 with Allow, for a request no route takes.
void AnswerUnrouted(const Request& req, const RouteMatch& match, Response& res) {
  if (match.allowed_methods.empty()) {
    WriteError(res, HttpError{404, "not_found",
                              "no route for " + Clip(req.method) + " " + Clip(req.path), {}});
    return;
  }
  std::string allow;
  for (const auto& m : match.allowed_methods) allow += (allow.empty() ? "" : ", ") + m;
  res.set_header("Allow", allow);
  WriteError(res, HttpError{405, "method_not_allowed",
                            "method " + Clip(req.method) + " not allowed here (allowed: " + allow +
                                ")",
                            {}});
}

// The request's media type, query and body against the route's declaration;
// fills ctx.body. The refusal, if any.
std::optional<HttpError> CheckRequest(const Route& route, RequestContext& ctx) {
  const Request& req = ctx.req;
  if (route.json_body && !IsJsonContentType(req.get_header_value("Content-Type"))) {
    return HttpError{415, "unsupported_media_type",
                     "the request body must be JSON (Content-Type: application/json)", {}};
  }
  for (const auto& [name, value] : req.params) {
    const bool known = std::any_of(route.query.begin(), route.query.end(),
                                   [&](const QueryParam& q) { return q.name == name; });
    if (!known) {
      return ToHttpError(api::Status::InvalidArgument("unknown query parameter", Clip(name, 64)));
    }
  }
  if (route.json_body) {
    auto body = api::ParseJsonObject(req.body);
    if (!body.ok()) return ToHttpError(body.status());
    ctx.body = std::move(*body);
  } else if (!req.body.empty() && !route.raw_body) {
    return ToHttpError(api::Status::InvalidArgument("this request takes no body"));
  }
  return std::nullopt;
}

// A JSON value of the wrong type or range that a handler read without
// api::JsonFields: the client's bytes, so a 400 (and audited), never a 500.
HttpError JsonValueError(const nlohmann::json::exception& e, const RequestContext& ctx) {
  std::string what = e.what();
  if (const auto close = what.find("] ");
      what.starts_with("[json.exception") && close != std::string::npos) {
    what = what.substr(close + 2);
  }
  return ToHttpError(api::Status::InvalidArgument("invalid value in the request: " + Clip(what),
                                                  ctx.body.is_null() ? "" : "body"));
}

}  // namespace

void HttpServer::Dispatch(const Request& req, Response& res, const UploadBody* upload,
                          Preadmission preadmitted) {
  const RouteMatch match = routes_.Match(req.method, req.path);
  if (!match.route) {
    if (match.allowed_methods.empty() && static_files_ && static_files_->Serve(req, res)) return;
    AnswerUnrouted(req, match, res);
    return;
  }
  const Route& route = *match.route;
  RequestContext ctx{req, res, match.path, std::nullopt, nullptr, upload};
  // The route's audit declaration decides who writes the entry of a
  // success; the dispatcher writes that of every refusal (Audit).
  auto refuse = [&](const HttpError& error) {
    WriteError(res, error);
    if (route.audit != Audit::kNever) WriteAudit(ctx, std::to_string(error.http_status) + " " + error.code);
  };
  try {
    if (preadmitted.route == &route) {
      ctx.user = std::move(preadmitted.user);
    } else {
      RouteAdmission admitted =
          AdmitTo(route, req.method, req.path, req.get_header_value("Authorization"), req.remote_addr);
      if (admitted.refusal) {
        for (const auto& [name, value] : admitted.headers) res.set_header(name, value);
        WriteError(res, *admitted.refusal);
        return;
      }
      ctx.user = std::move(admitted.user);
    }
    if (auto refusal = CheckRequest(route, ctx)) {
      refuse(*refusal);
      return;
    }
    auto reply = route.handler(ctx);
    if (!reply.ok()) {
      if (reply.status().code() == api::ErrorCode::kInternal ||
          reply.status().code() == api::ErrorCode::kDataLoss) {
        std::cerr << "fesbench-server: " << req.method << " " << Clip(req.path) << ": "
                  << reply.status().ToString() << std::endl;
      }
      refuse(ToHttpError(reply.status()));
      return;
    }
    if (!reply->raw) WriteJson(res, reply->status, reply->body);
    if (route.audit == Audit::kDispatcher) WriteAudit(ctx, std::to_string(reply->status));
  } catch (const nlohmann::json::exception& e) {
    refuse(JsonValueError(e, ctx));
  } catch (const std::exception& e) {
    std::cerr << "fesbench-server: internal error on " << req.method << " " << Clip(req.path)
              << ": " << e.what() << std::endl;
    WriteError(res, HttpError{500, "internal", "internal server error", {}});
  }
}

}  // namespace fesbench::server::http
