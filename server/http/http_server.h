#pragma once

/// @file
/// The HTTP front end (docs/API.md; docs/ARCHITECTURE.md, "The HTTP front
/// end"). The connections are ours, so that slow or crowding clients can
/// never keep an e-stop out (docs/SAFETY.md, "The e-stop under load");
/// Boost.Beast parses each framed request (request_parser.h), the route
/// table dispatches it (router.h) and response_writer.h writes the answer:
///
/// - We bind the listening socket ourselves (SO_REUSEADDR, never
///   SO_REUSEPORT): a second server on a port in use fails "address in use".
/// - Worker threads share one epoll set; the listening socket is one-shot,
///   so one worker at a time accepts a batch of connections. A worker reads what a connection
///   has sent (non-blocking) and frames it (request_framing.h); only a whole
///   request (head and body) is parsed and dispatched, from memory (an
///   upload: its head, the body being in a file). Deadlines (below) hold whatever
///   pace the bytes come at, and an idle keep-alive connection is closed
///   after `keep_alive_timeout`. Slow clients therefore hold no thread. Pipelined requests are answered in order; a request
///   whose client half-closed is still answered.
/// - Admission: at most `max_connections` requests are handled at once
///   (plus `max_streams` event streams); a request beyond that is answered
///   503 at once. Two more workers are kept for the urgent routes (e-stop,
///   health), which are never refused for load and never wait behind other
///   requests. Connections are always accepted: beyond
///   `max_open_connections` in all, or `max_connections_per_address` from
///   one address, the oldest connection that no worker is handling (idle
///   ones first) is closed to make room, so idle or half-sent connections
///   can never keep an e-stop out (docs/SAFETY.md, "The e-stop under load").
/// - Heads first: a request's head must be complete within `head_timeout`
///   of its first byte. Before any of a body is read, the route, the bearer token, the
///   role and the media type are checked on the head alone; a refusal is
///   answered at once and the connection closed, and `100 Continue` is sent
///   only to an admitted request.
/// - Uploads (request_framing.h IsUpload) are spooled to an unlinked
///   temporary file in `upload_dir` as they arrive (at most
///   `max_spooled_bytes` of them at once; beyond: 503), never held in
///   memory; the handler reads them from RequestContext::upload. An upload's
///   body may stall at most `request_timeout` between bytes and must be
///   complete within `request_timeout` plus one second per MiB.
/// - HTTPS (both TLS paths set) runs in the same loop over OpenSSL.
///
/// - Event streams (Response::set_event_stream) are sent chunked by the
///   worker that answered the request, which calls the stream's source until
///   it is done, the client leaves or the server stops.
///
/// Dispatch order for each request: route (404 / 405 with Allow), bearer
/// token (401, or 429 for an address presenting many wrong tokens), role
/// (403), Content-Type (415), JSON body (400), handler.
/// Any exception from a client's bytes ends as a 400 (never a 500).
/// State-changing requests (POST, PUT, PATCH, DELETE) by an authenticated
/// user are audited as their route declares (Route::audit): by the
/// dispatcher, or by the handler in the transaction of its change; refusals
/// are audited here.

#include <atomic>
#include <condition_variable>
#include <map>
#include <mutex>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "api/status.h"
#include "server/http/auth.h"
#include "server/http/errors.h"
#include "server/http/router.h"
#include "server/http/static_files.h"
#include "server/http/stream_slots.h"
#include "storage/database.h"

typedef struct ssl_ctx_st SSL_CTX;

namespace fesbench::server::http {

struct HttpServerOptions {
  std::string bind_address = "127.0.0.1";
  int port = 8080;  ///< 0: the system picks a free port (see Bind()).
  std::string tls_cert_path;  ///< both set: HTTPS.
  std::string tls_key_path;
  std::size_t max_body_bytes = 1 << 20;  ///< larger bodies: 413.
  /// Upload bodies (request_framing.h IsUpload: trial imports) may be this
  /// large, and get one more second to arrive per MiB.
  std::size_t max_upload_bytes = std::size_t{256} << 20;
  std::size_t max_headers = 64;          ///< more header lines: 431.
  std::size_t max_head_bytes = 16 * 1024;  ///< request line and headers; beyond: 431.
  /// A request's head must be complete within this of its first byte;
  /// otherwise 408.
  std::chrono::milliseconds head_timeout{3000};
  /// A body must be complete within this of its head (uploads: may stall at
  /// most this long, see above); otherwise 408 and the connection is closed.
  std::chrono::milliseconds request_timeout{5000};
  std::chrono::milliseconds write_timeout{5000};  ///< per blocked write.
  std::chrono::milliseconds keep_alive_timeout{5000};  ///< idle connection: closed.
  std::size_t keep_alive_max_count = 10000;  ///< requests per connection.
  std::size_t max_connections = 48;  ///< requests handled at once (beyond: 503).
  std::size_t max_streams = 16;      ///< open event streams (beyond: 503).
  std::size_t max_open_connections = 512;  ///< open connections (beyond: the oldest idle closed).
  std::size_t max_connections_per_address = 256;  ///< from one client address (the same).
  /// Where uploads are spooled; empty: $TMPDIR, or /tmp.
  std::string upload_dir;
  /// Upload bytes spooled at once, all connections together (beyond: 503).
  std::size_t max_spooled_bytes = std::size_t{1} << 30;
  /// "METHOD /path" of routes that are never refused for load and never
  /// wait behind other requests.
  std::vector<std::string> urgent_routes = {"POST /api/v1/bench/estop", "GET /api/v1/health",
                                            "HEAD /api/v1/health"};
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
  /// be bound (the message says "address in use" when another process
  /// listens there), kInvalidArgument for unreadable TLS files.
  api::Result<int> Bind();
  /// Serves until Stop(); returns false if the server failed.
  bool Run();
  /// Stops accepting, ends event streams, lets requests in progress finish,
  /// closes every connection. Thread-safe, may be called before Run
  /// returns; returns once Run has returned (or at once if it never ran).
  void Stop();

  const RouteTable& routes() const { return routes_; }

  struct Connection;  ///< one client connection (http_server.cc).

 private:
  /// The one role check (docs/API.md, "Roles and permissions"): for a route
  /// that needs a permission, the bearer token's user if its role has it,
  /// else the refusal (401, 403, or 429 for an address presenting many wrong
  /// tokens) with the header fields that go with it.
  struct RouteAdmission {
    std::optional<storage::User> user;
    std::optional<HttpError> refusal;
    std::vector<std::pair<std::string, std::string>> headers;
  };
  RouteAdmission AdmitTo(const Route& route, std::string_view method, std::string_view path,
                         std::string_view authorization, const std::string& address);
  /// A request admitted on its head alone (Preadmit), before its body came.
  struct Preadmission {
    const Route* route = nullptr;
    std::optional<storage::User> user;
  };
  void Dispatch(const Request& req, Response& res, const UploadBody* upload,
                Preadmission preadmitted);
  bool SendEventStream(Connection& c, Response& res);
  /// Appends the audit entry of a state-changing request by a signed-in user.
  void WriteAudit(const RequestContext& ctx, const std::string& outcome);

  // The connection loop (http_server.cc).
  void WorkerLoop();
  void SweepLoop();
  void Accept();
  void Serve(std::uint64_t id);
  void HandleBytes(Connection& c);
  bool ProcessOne(Connection& c, std::string_view request, bool last, const UploadBody* upload);
  bool Answer(Connection& c, std::string_view request, std::size_t consumed, bool keep_alive,
              const UploadBody* upload);
  std::optional<HttpError> Preadmit(Connection& c, std::string_view method,
                                    std::string_view path, std::string_view authorization,
                                    std::string_view content_type, std::string& extra_headers);
  bool StartSpool(Connection& c, std::size_t head_length, std::size_t body_bytes,
                  bool expect_continue);
  bool SpoolBody(Connection& c);
  void EndSpool(Connection& c);
  bool EvictOne(const std::string* address, std::uint64_t except);
  void Rearm(Connection& c, bool want_write = false);
  void Refuse(Connection& c, const HttpError& error, bool close, std::string_view extra_headers = {});
  void Close(Connection& c, bool graceful);
  bool IsUrgent(std::string_view method, std::string_view path) const;

  HttpServerOptions options_;
  RouteTable routes_;
  Authenticator& auth_;
  storage::Database& db_;
  StreamSlots& slots_;
  std::optional<StaticFiles> static_files_;
  SSL_CTX* tls_ = nullptr;
  int listen_fd_ = -1;
  int epoll_fd_ = -1;
  int wake_fd_ = -1;  ///< eventfd: set once on Stop, wakes every worker.
  std::size_t workers_ = 0;
  std::atomic<std::size_t> busy_{0};  ///< requests being handled now.
  std::mutex connections_mutex_;
  std::map<std::uint64_t, std::shared_ptr<Connection>> connections_;  ///< oldest first.
  std::map<std::string, std::size_t, std::less<>> per_address_;  ///< open connections per address.
  std::atomic<std::size_t> spooled_bytes_{0};  ///< upload bytes reserved by spooling connections.
  std::uint64_t next_id_ = 1;
  std::mutex run_mutex_;
  std::condition_variable run_cv_;
  std::atomic<bool> running_{false};
  std::atomic<bool> stop_requested_{false};
};

/// A short, secret-free summary of a request body for the audit log
/// (compact JSON, at most 512 characters).
std::string AuditSummary(const nlohmann::json& body);

}  // namespace fesbench::server::http
