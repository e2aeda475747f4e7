#pragma once
// The REST API of the service over HTTP (cpp-httplib), described in
// docs/openapi.yaml (served at /api/v1/openapi.yaml) and docs/service.md.
//
// Safe by default: it listens on the loopback address unless told
// otherwise; every request to the API carries the token (Authorization:
// Bearer TOKEN, or the dashboard's cookie, else 401; the dashboard's page
// and chart library, which hold no data, and the sign-in that sets the
// cookie are the exceptions); a body larger than max_body_bytes is refused (413); a body that
// is not JSON (400), a bad spec (400, the message `calib run` gives), a path
// out of the data roots (403), an unknown job (404) or a conflict (409) is
// answered {"error": message, "field": the request field}; an unexpected
// error is a 500 with its message, never a crash. Requests are answered on
// a pool of threads of their own, so the server answers while jobs run.

#include "calib/service/job_service.h"

#include <cstddef>
#include <memory>
#include <string>
#include <string_view>

namespace calib::service {

struct HttpOptions {
  /// Address to listen on; the loopback address unless told otherwise.
  std::string listen = "127.0.0.1";
  /// 0: any free port (Bind returns it).
  int port = 8080;
  /// Largest request body accepted (bytes).
  size_t max_body_bytes = 1 << 20;
  /// Every request must carry it.
  std::string token;
};

/// The OpenAPI description (docs/openapi.yaml, compiled in).
const char* OpenApiYaml();
/// The dashboard's page (dashboard/index.html) and its chart library
/// (Chart.js from npm), compiled in.
std::string_view DashboardPage();
std::string_view DashboardChartJs();

class HttpApi {
 public:
  HttpApi(JobService& service, HttpOptions options);
  ~HttpApi();
  HttpApi(const HttpApi&) = delete;
  HttpApi& operator=(const HttpApi&) = delete;

  /// Binds the address; returns the port. Throws std::runtime_error naming
  /// the address when it cannot.
  int Bind();
  /// Answers requests until Stop() (from another thread or a signal
  /// handler's thread).
  void Serve();
  void Stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace calib::service
