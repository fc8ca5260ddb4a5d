#include "server/http/http_server.h"

#include <httplib.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <exception>
#include <iostream>
#include <thread>

#include "server/http/errors.h"
#include "server/http/json_fields.h"
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

// Ask the library to close the connection after this response: a refused
// request's body was not read and must not be taken for the next request.
void CloseAfterResponse(const httplib::Request& req, httplib::Response& res) {
  // The Request is a non-const local of the library's request loop; the
  // handler API hands it out const only by convention.
  const_cast<httplib::Request&>(req).set_header("Connection", "close");
  res.set_header("Connection", "close");
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

HttpServer::~HttpServer() { Stop(); }

api::Result<int> HttpServer::Bind() {
  if (!options_.tls_cert_path.empty() || !options_.tls_key_path.empty()) {
    if (options_.tls_cert_path.empty() || options_.tls_key_path.empty()) {
      return api::Status::InvalidArgument("TLS needs both a certificate and a key", "tls-cert");
    }
    auto tls = std::make_unique<httplib::SSLServer>(options_.tls_cert_path.c_str(),
                                                    options_.tls_key_path.c_str());
    if (!tls->is_valid()) {
      return api::Status::InvalidArgument("cannot load the TLS certificate or key", "tls-cert");
    }
    server_ = std::move(tls);
  } else {
    server_ = std::make_unique<httplib::Server>();
  }
  httplib::Server& svr = *server_;

  const std::size_t workers = options_.max_connections + options_.max_streams;
  svr.new_task_queue = [workers] { return new httplib::ThreadPool(workers); };
  svr.set_tcp_nodelay(true);
  svr.set_payload_max_length(options_.max_body_bytes);
  svr.set_read_timeout(options_.read_timeout);
  svr.set_write_timeout(options_.write_timeout);
  svr.set_keep_alive_timeout(options_.keep_alive_timeout.count());
  svr.set_keep_alive_max_count(options_.keep_alive_max_count);
  svr.set_default_headers({{"Cache-Control", "no-store"}, {"X-Content-Type-Options", "nosniff"}});

  svr.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    // REMOTE_ADDR, REMOTE_PORT, LOCAL_ADDR, LOCAL_PORT are added by the library.
    if (req.headers.size() > options_.max_headers + 4) {
      CloseAfterResponse(req, res);
      WriteError(res, HttpError{431, "too_many_headers",
                                "at most " + std::to_string(options_.max_headers) +
                                    " header lines are accepted",
                                {}});
      return httplib::Server::HandlerResponse::Handled;
    }
    if (req.has_header("Transfer-Encoding")) {
      CloseAfterResponse(req, res);
      WriteError(res, HttpError{411, "length_required",
                                "request bodies sent with Transfer-Encoding (chunked) are not "
                                "accepted; send Content-Length",
                                {}});
      return httplib::Server::HandlerResponse::Handled;
    }
    if (!req.has_header("Content-Length")) {
      // No Content-Length and no Transfer-Encoding: the request has no body
      // (RFC 9112 §6.3). Say so, or the library would read until the peer
      // closes.
      const_cast<httplib::Request&>(req).set_header("Content-Length", "0");
    }
    if ((req.method == "GET" || req.method == "HEAD") && req.has_header("Content-Length") &&
        req.get_header_value("Content-Length") != "0") {
      CloseAfterResponse(req, res);
      WriteError(res, HttpError{400, "bad_request", "GET requests take no body", {}});
      return httplib::Server::HandlerResponse::Handled;
    }
    return httplib::Server::HandlerResponse::Unhandled;
  });

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

  int port = options_.port;
  if (port == 0) {
    port = svr.bind_to_any_port(options_.bind_address);
    if (port <= 0) {
      return api::Status::Unavailable("cannot bind a port on " + options_.bind_address);
    }
  } else if (!svr.bind_to_port(options_.bind_address, port)) {
    return api::Status::Unavailable("cannot bind " + options_.bind_address + ":" +
                                    std::to_string(port));
  }
  return port;
}

bool HttpServer::Run() {
  if (!server_) return false;
  running_.store(true);
  if (stop_requested_.load()) {
    running_.store(false);
    return true;
  }
  const bool ok = server_->listen_after_bind();
  running_.store(false);
  return ok || stop_requested_.load();
}

void HttpServer::Stop() {
  stop_requested_.store(true);
  slots_.Shutdown();
  if (!server_) return;
  // listen_after_bind sets the library's running flag a moment after Run
  // starts: keep asking until Run has returned.
  while (running_.load()) {
    server_->stop();
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
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
    } else if (!req.body.empty()) {
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
  } catch (const std::exception& e) {
    std::cerr << "fesbench-server: internal error on " << req.method << " " << Clip(req.path)
              << ": " << e.what() << std::endl;
    WriteError(res, HttpError{500, "internal", "internal server error", {}});
  }
}

}  // namespace fesbench::server::http
