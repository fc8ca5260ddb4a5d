#pragma once

/// @file
/// A small client of the fesbench HTTP/JSON API (docs/API.md) over HTTP or
/// HTTPS (cpp-httplib with OpenSSL). Every call either returns the parsed
/// JSON body or throws CliError: kExitServer with the server's error message
/// for a 4xx/5xx answer, kExitUnreachable when no answer came.
///
/// HTTPS verifies the server certificate against the system CAs, or the PEM
/// file named by FESBENCH_CA_FILE (for a lab's self-signed certificate).

#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "api/envelope.h"
#include "api/status.h"
#include "clients/cli/cli.h"
#include "clients/cli/config.h"

namespace httplib {
class Client;
}

namespace fesbench::cli {

/// The items of a page answer (api::Page); CliError (server class) when
/// `page` is not one.
nlohmann::json PageItems(const nlohmann::json& page, const std::string& path);

/// The elements of the array `items` read by `from`; CliError (server
/// class) naming `what` for one it cannot read.
template <typename T>
std::vector<T> ItemsFromServer(const nlohmann::json& items,
                               api::Result<T> (*from)(const nlohmann::json&),
                               std::string_view what) {
  std::vector<nlohmann::json> list;
  if (items.is_array()) list.assign(items.begin(), items.end());
  api::Result<std::vector<T>> read = api::ItemsFromJson(list, from);
  if (!read.ok()) {
    throw CliError::Server("server sent an unreadable " + std::string(what) + ": " +
                           read.status().ToString());
  }
  return *std::move(read);
}

class ApiClient {
 public:
  /// `connection.server` as normalised by NormaliseServerUrl.
  explicit ApiClient(CliConfig connection);
  ~ApiClient();
  ApiClient(const ApiClient&) = delete;
  ApiClient& operator=(const ApiClient&) = delete;

  /// `path` is relative to /api/v1 and starts with '/', e.g. "/subjects".
  nlohmann::json Get(const std::string& path);
  nlohmann::json Post(const std::string& path, const nlohmann::json& body = nullptr);
  nlohmann::json Put(const std::string& path, const nlohmann::json& body);
  /// The body of a non-JSON answer (an archive, a CSV file), as bytes.
  std::string GetBytes(const std::string& path);
  /// POSTs `body` with `content_type` (an upload); returns the JSON answer.
  nlohmann::json PostBytes(const std::string& path, const std::string& body,
                           const std::string& content_type);
  nlohmann::json Patch(const std::string& path, const nlohmann::json& body);
  nlohmann::json Delete(const std::string& path);

  /// Every item of a paged list (follows next_cursor; `query` without
  /// limit/cursor, e.g. "subject_id=3" or "").
  nlohmann::json GetAllPages(const std::string& path, const std::string& query);
  /// Every item of a paged list, each read by `from` (api/…FromJson);
  /// CliError (server class) naming `what` for an item it cannot read.
  template <typename T>
  std::vector<T> GetAllPagesOf(const std::string& path, const std::string& query,
                               api::Result<T> (*from)(const nlohmann::json&),
                               std::string_view what) {
    return ItemsFromServer(GetAllPages(path, query), from, what);
  }
  /// The items of a list answer ({"items": [...]}) read by `from`.
  template <typename T>
  std::vector<T> GetItemsOf(const std::string& path,
                            api::Result<T> (*from)(const nlohmann::json&), std::string_view what) {
    return ItemsFromServer(PageItems(Get(path), path), from, what);
  }

  /// Follows a Server-Sent Events stream; `on_event(event, data)` returns
  /// false to stop reading. Returns when the server closes the stream.
  void Stream(const std::string& path,
              const std::function<bool(const std::string&, const nlohmann::json&)>& on_event);

  const std::string& server() const { return connection_.server; }

 private:
  nlohmann::json Handle(const std::string& method, const std::string& path, int status,
                        const std::string& body) const;
  [[noreturn]] void Unreachable(const std::string& what) const;

  CliConfig connection_;
  std::unique_ptr<httplib::Client> client_;
};

/// The one-line message of an error answer: the server's
/// `{"error": {"message", "field"}}` if present, with the HTTP status.
std::string ServerErrorMessage(int status, const std::string& body);

/// Percent-encodes a query value.
std::string UrlEncode(const std::string& value);

}  // namespace fesbench::cli
