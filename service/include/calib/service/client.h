#pragma once
// A client of the service's REST API (`calib submit`, `calib status`,
// `calib cancel`, `calib jobs --server`): JSON in, JSON out.

#include <nlohmann/json.hpp>

#include <memory>
#include <string>

namespace calib::service {

class ServiceClient {
 public:
  /// `url`: "http://HOST:PORT". Throws std::invalid_argument for a URL that
  /// is not http://HOST[:PORT].
  ServiceClient(const std::string& url, std::string token);
  ~ServiceClient();
  ServiceClient(const ServiceClient&) = delete;
  ServiceClient& operator=(const ServiceClient&) = delete;

  /// The answer's JSON body. Throws std::runtime_error naming the server
  /// and the request: it cannot be reached, or it refused (the status and
  /// the server's message, which names the field).
  nlohmann::json Get(const std::string& path);
  nlohmann::json Post(const std::string& path, const nlohmann::json& body);
  nlohmann::json Delete(const std::string& path);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace calib::service
