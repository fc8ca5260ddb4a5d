#include "clients/cli/api_client.h"

#include <httplib.h>

#include <cstdlib>
#include <map>

namespace fesbench::cli {

namespace {

using nlohmann::json;

constexpr const char* kApiPrefix = "/api/v1";

}  // namespace

std::string ServerErrorMessage(int status, const std::string& body) {
  const json j = json::parse(body, nullptr, false);
  std::string message;
  if (!j.is_discarded()) {
    if (const std::optional<api::Status> error = api::ErrorAnswerFromJson(j)) {
      message = error->message();
      if (!error->field().empty()) message += " (field " + error->field() + ")";
    }
  }
  if (message.empty()) message = body.substr(0, 200);
  return "server: " + message + " [HTTP " + std::to_string(status) + "]";
}

json PageItems(const json& page, const std::string& path) {
  api::Result<api::Page> read = api::PageFromJson(page);
  if (!read.ok()) {
    throw CliError::Server("server: " + path + " did not answer with a page of items");
  }
  return json(std::move(read->items));
}

std::string UrlEncode(const std::string& value) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string out;
  for (unsigned char c : value) {
    if (std::isalnum(c) || c == '-' || c == '_' || c == '.' || c == '~') {
      out += static_cast<char>(c);
    } else {
      out += '%';
      out += kHex[c >> 4];
      out += kHex[c & 15];
    }
  }
  return out;
}

ApiClient::ApiClient(CliConfig connection) : connection_(std::move(connection)) {
  client_ = std::make_unique<httplib::Client>(connection_.server);
  client_->set_connection_timeout(5);
  client_->set_read_timeout(30);
  client_->set_write_timeout(10);
  client_->set_keep_alive(true);
  if (!connection_.token.empty()) client_->set_bearer_token_auth(connection_.token.c_str());
  if (const char* ca = std::getenv("FESBENCH_CA_FILE"); ca != nullptr && ca[0] != '\0') {
    client_->set_ca_cert_path(ca);
  }
  client_->enable_server_certificate_verification(true);
}

ApiClient::~ApiClient() = default;

void ApiClient::Unreachable(const std::string& what) const {
  static const std::map<std::string, std::string> kPlain = {
      {"Connection", "connection refused or host unreachable"},
      {"ConnectionTimeout", "connection timed out"},
      {"Read", "the connection broke while reading the answer"},
      {"Write", "the connection broke while sending the request"},
      {"SSLConnection", "TLS handshake failed"},
      {"SSLServerVerification",
       "the server's certificate is not trusted (set FESBENCH_CA_FILE to its CA file)"},
  };
  const auto plain = kPlain.find(what);
  const std::string detail = plain == kPlain.end() ? what : plain->second;
  throw CliError::Unreachable("cannot reach " + connection_.server + ": " + detail);
}

json ApiClient::Handle(const std::string& method, const std::string& path, int status,
                       const std::string& body) const {
  if (status >= 400) throw CliError::Server(ServerErrorMessage(status, body));
  if (body.empty()) return nullptr;
  json j = json::parse(body, nullptr, false);
  if (j.is_discarded()) {
    throw CliError::Server("server: " + method + " " + path + " answered with malformed JSON");
  }
  return j;
}

json ApiClient::Get(const std::string& path) {
  auto result = client_->Get(kApiPrefix + path);
  if (!result) Unreachable(httplib::to_string(result.error()));
  return Handle("GET", path, result->status, result->body);
}

json ApiClient::Post(const std::string& path, const json& body) {
  const std::string text = body.is_null() ? std::string() : body.dump();
  auto result = body.is_null() ? client_->Post(kApiPrefix + path)
                               : client_->Post(kApiPrefix + path, text, "application/json");
  if (!result) Unreachable(httplib::to_string(result.error()));
  return Handle("POST", path, result->status, result->body);
}

std::string ApiClient::GetBytes(const std::string& path) {
  auto result = client_->Get(kApiPrefix + path);
  if (!result) Unreachable(httplib::to_string(result.error()));
  if (result->status >= 400)
    throw CliError::Server(ServerErrorMessage(result->status, result->body));
  return result->body;
}

json ApiClient::PostBytes(const std::string& path, const std::string& body,
                          const std::string& content_type) {
  auto result = client_->Post(kApiPrefix + path, body, content_type);
  if (!result) Unreachable(httplib::to_string(result.error()));
  return Handle("POST", path, result->status, result->body);
}

json ApiClient::Put(const std::string& path, const json& body) {
  const std::string text = body.dump();
  auto result = client_->Put(kApiPrefix + path, text, "application/json");
  if (!result) Unreachable(httplib::to_string(result.error()));
  return Handle("PUT", path, result->status, result->body);
}

json ApiClient::Patch(const std::string& path, const json& body) {
  const std::string text = body.dump();
  auto result = client_->Patch(kApiPrefix + path, text, "application/json");
  if (!result) Unreachable(httplib::to_string(result.error()));
  return Handle("PATCH", path, result->status, result->body);
}

json ApiClient::Delete(const std::string& path) {
  auto result = client_->Delete(kApiPrefix + path);
  if (!result) Unreachable(httplib::to_string(result.error()));
  return Handle("DELETE", path, result->status, result->body);
}

json ApiClient::GetAllPages(const std::string& path, const std::string& query) {
  json items = json::array();
  std::string cursor;
  for (;;) {
    std::string url = path + "?limit=500";
    if (!query.empty()) url += "&" + query;
    if (!cursor.empty()) url += "&cursor=" + UrlEncode(cursor);
    api::Result<api::Page> page = api::PageFromJson(Get(url));
    if (!page.ok()) {
      throw CliError::Server("server: " + path + " did not answer with a page of items");
    }
    for (auto& item : page->items) items.push_back(std::move(item));
    if (!page->next_cursor) break;
    cursor = *page->next_cursor;
  }
  return items;
}

void ApiClient::Stream(const std::string& path,
                       const std::function<bool(const std::string&, const json&)>& on_event) {
  // A separate connection: the stream stays open while other calls go on.
  httplib::Client stream(connection_.server);
  stream.set_connection_timeout(5);
  stream.set_read_timeout(30);  // the server sends a keep-alive comment every 2 s
  if (!connection_.token.empty()) stream.set_bearer_token_auth(connection_.token.c_str());
  if (const char* ca = std::getenv("FESBENCH_CA_FILE"); ca != nullptr && ca[0] != '\0') {
    stream.set_ca_cert_path(ca);
  }
  int status = 0;
  std::string error_body;
  std::string buffer;
  bool stopped = false;
  auto result = stream.Get(
      kApiPrefix + path,
      [&](const httplib::Response& response) {
        status = response.status;
        return true;
      },
      [&](const char* data, std::size_t n) {
        if (status >= 400) {
          error_body.append(data, n);
          return true;
        }
        buffer.append(data, n);
        std::size_t end;
        while ((end = buffer.find("\n\n")) != std::string::npos) {
          const std::string frame = buffer.substr(0, end);
          buffer.erase(0, end + 2);
          std::string event, data_text;
          std::size_t pos = 0;
          while (pos < frame.size()) {
            std::size_t eol = frame.find('\n', pos);
            if (eol == std::string::npos) eol = frame.size();
            const std::string line = frame.substr(pos, eol - pos);
            if (line.rfind("event: ", 0) == 0) event = line.substr(7);
            if (line.rfind("data: ", 0) == 0) data_text += line.substr(6);
            pos = eol + 1;
          }
          if (event.empty()) continue;  // a keep-alive comment
          json payload = json::parse(data_text, nullptr, false);
          if (payload.is_discarded()) payload = nullptr;
          if (!on_event(event, payload)) {
            stopped = true;
            return false;
          }
        }
        return true;
      });
  if (stopped) return;
  if (status >= 400) throw CliError::Server(ServerErrorMessage(status, error_body));
  if (!result) Unreachable(httplib::to_string(result.error()));
}

}  // namespace fesbench::cli
