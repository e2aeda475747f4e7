#include "calib/service/client.h"

#include <fmt/format.h>
#include <httplib.h>

#include <stdexcept>

namespace calib::service {

struct ServiceClient::Impl {
  std::string url;
  httplib::Client client;
  Impl(const std::string& u, const std::string& token) : url(u), client(u) {
    client.set_bearer_token_auth(token.c_str());
    client.set_connection_timeout(5);
    client.set_read_timeout(60);
  }

  nlohmann::json Answer(const std::string& what, const httplib::Result& result) {
    if (!result) {
      throw std::runtime_error(fmt::format("{}: {}: cannot reach the server: {}", url, what,
                                           httplib::to_string(result.error())));
    }
    nlohmann::json body;
    try {
      body = nlohmann::json::parse(result->body);
    } catch (const nlohmann::json::exception&) {
      body = {{"error", result->body}};
    }
    if (result->status >= 400) {
      throw std::runtime_error(fmt::format("{}: {}: HTTP {}: {}", url, what, result->status,
                                           body.value("error", result->body)));
    }
    return body;
  }
};

ServiceClient::ServiceClient(const std::string& url, std::string token) {
  if (url.rfind("http://", 0) != 0 || url.size() <= 7) {
    throw std::invalid_argument(fmt::format("--server = '{}': expected http://HOST:PORT", url));
  }
  impl_ = std::make_unique<Impl>(url, token);
}

ServiceClient::~ServiceClient() = default;

nlohmann::json ServiceClient::Get(const std::string& path) {
  return impl_->Answer("GET " + path, impl_->client.Get(path.c_str()));
}

nlohmann::json ServiceClient::Post(const std::string& path, const nlohmann::json& body) {
  return impl_->Answer("POST " + path, impl_->client.Post(path.c_str(), body.dump(), "application/json"));
}

nlohmann::json ServiceClient::Delete(const std::string& path) {
  return impl_->Answer("DELETE " + path, impl_->client.Delete(path.c_str()));
}

}  // namespace calib::service
