#pragma once

/// @file
/// The HTTP front end (DESIGN.md §8) on cpp-httplib 0.11, hardened as
/// NOTES-deps.md says it must be: explicit payload limit, read/write
/// timeouts, keep-alive limits, TCP_NODELAY, a worker pool sized for
/// connections plus event streams, request bodies sent chunked refused,
/// header count bounded, JSON errors for everything (including errors the
/// library produces itself), and a catch-all that turns an unexpected
/// exception into a logged 500.
///
/// Dispatch order for each request: route (404 / 405 with Allow), bearer
/// token (401), role (403), Content-Type (415), JSON body (400), handler.
/// State-changing requests (POST, PUT, DELETE) by an authenticated user are
/// audited: handlers that change storage audit in the same transaction;
/// refusals are audited here.

#include <atomic>
#include <chrono>
#include <cstddef>
#include <memory>
#include <optional>
#include <string>

#include "api/status.h"
#include "server/http/auth.h"
#include "server/http/router.h"
#include "server/http/static_files.h"
#include "server/http/stream_slots.h"
#include "storage/database.h"

namespace httplib {
class Server;
}

namespace fesbench::server::http {

struct HttpServerOptions {
  std::string bind_address = "127.0.0.1";
  int port = 8080;  ///< 0: the system picks a free port (see Bind()).
  std::string tls_cert_path;  ///< both set: HTTPS.
  std::string tls_key_path;
  std::size_t max_body_bytes = 1 << 20;  ///< larger bodies: 413.
  std::size_t max_headers = 64;          ///< more header lines: 431.
  std::chrono::seconds read_timeout{5};
  std::chrono::seconds write_timeout{5};
  std::chrono::seconds keep_alive_timeout{5};
  std::size_t keep_alive_max_count = 10000;  ///< requests per connection.
  std::size_t max_connections = 48;  ///< concurrent keep-alive connections served at once.
  std::size_t max_streams = 16;      ///< open event streams (beyond: 503).
  /// The web client's built files, served at / without a token for GET
  /// and HEAD of paths no route matches (static_files.h). Empty: none.
  std::string web_root;
};

class HttpServer {
 public:
  /// @param routes the API; @param db receives audit entries of refusals.
  /// `slots` is shared with the stream routes (capacity max_streams).
  HttpServer(HttpServerOptions options, RouteTable routes, Authenticator& auth,
             storage::Database& db, StreamSlots& slots);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  /// Binds the listening socket; the port bound. kUnavailable if it cannot
  /// be bound, kInvalidArgument for unreadable TLS files.
  api::Result<int> Bind();
  /// Serves until Stop(); returns false if the server failed.
  bool Run();
  /// Stops accepting, ends event streams, waits for workers. Thread-safe,
  /// may be called before Run returns.
  void Stop();

  const RouteTable& routes() const { return routes_; }

 private:
  void Dispatch(const httplib::Request& req, httplib::Response& res);
  void AuditRefusal(const RequestContext& ctx, int status, const std::string& code);

  HttpServerOptions options_;
  RouteTable routes_;
  Authenticator& auth_;
  storage::Database& db_;
  StreamSlots& slots_;
  std::optional<StaticFiles> static_files_;
  std::unique_ptr<httplib::Server> server_;
  std::atomic<bool> running_{false};
  std::atomic<bool> stop_requested_{false};
};

/// A short, secret-free summary of a request body for the audit log
/// (compact JSON, at most 512 characters).
std::string AuditSummary(const nlohmann::json& body);

}  // namespace fesbench::server::http
