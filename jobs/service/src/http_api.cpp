#include "calib/service/http_api.h"

#include "calib/service/service_error.h"

#include <fmt/format.h>
#include <httplib.h>
#include <spdlog/spdlog.h>

#include <fstream>
#include <sstream>

namespace calib::service {
namespace {

constexpr const char* kJson = "application/json";
// A job's name in a path: the job spec's rule for names.
constexpr const char* kName = "([A-Za-z0-9_.-]+)";

void Reply(httplib::Response& res, int status, const nlohmann::json& body) {
  res.status = status;
  res.set_content(body.dump(2) + "\n", kJson);
}

void ReplyError(httplib::Response& res, int status, const std::string& field,
                const std::string& message) {
  nlohmann::json body = {{"error", message}};
  if (!field.empty()) body["field"] = field;
  Reply(res, status, body);
}

// Compares in time independent of where the two differ.
bool SameToken(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return false;
  unsigned char diff = 0;
  for (size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

constexpr const char* kCookie = "calib_token";

// Whether the Cookie header holds calib_token=TOKEN as one of its
// "name=value" pairs (RFC 6265: separated by "; ").
bool CookieHoldsToken(const std::string& header, const std::string& token) {
  const std::string wanted = std::string(kCookie) + "=";
  size_t start = 0;
  while (start <= header.size()) {
    size_t end = header.find(';', start);
    if (end == std::string::npos) end = header.size();
    size_t first = header.find_first_not_of(' ', start);
    if (first < end && header.compare(first, wanted.size(), wanted) == 0) {
      return SameToken(header.substr(first + wanted.size(), end - first - wanted.size()), token);
    }
    start = end + 1;
  }
  return false;
}

// What may be asked without the token: the dashboard's page and chart
// library (no data in them) and the sign-in that checks the token.
bool Open(const httplib::Request& req) {
  return (req.method == "GET" && (req.path == "/" || req.path == "/dashboard/chart.umd.js")) ||
         (req.method == "POST" && req.path == "/api/v1/session");
}

nlohmann::json BodyJson(const httplib::Request& req) {
  if (req.body.empty()) return nlohmann::json::object();
  try {
    return nlohmann::json::parse(req.body);
  } catch (const nlohmann::json::exception& e) {
    throw ServiceError(400, "body", fmt::format("the body is not JSON: {}", e.what()));
  }
}

std::string ReadFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

std::string ContentType(const std::filesystem::path& path) {
  const std::string ext = path.extension().string();
  if (ext == ".json") return kJson;
  if (ext == ".csv") return "text/csv";
  if (ext == ".txt") return "text/plain; charset=utf-8";
  if (ext == ".png") return "image/png";
  if (ext == ".svg") return "image/svg+xml";
  if (ext == ".mp4") return "video/mp4";
  if (ext == ".html") return "text/html; charset=utf-8";
  return "application/octet-stream";
}

}  // namespace

struct HttpApi::Impl {
  JobService& service;
  HttpOptions options;
  httplib::Server server;

  Impl(JobService& s, HttpOptions o) : service(s), options(std::move(o)) { Routes(); }

  // Runs a handler; its ServiceError becomes the answer.
  template <typename F>
  httplib::Server::Handler Guarded(F handler) {
    return [handler](const httplib::Request& req, httplib::Response& res) {
      try {
        handler(req, res);
      } catch (const ServiceError& e) {
        ReplyError(res, e.status(), e.field(), e.what());
      }
    };
  }

  void Routes() {
    server.set_payload_max_length(options.max_body_bytes);
    server.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
      const std::string header = req.get_header_value("Authorization");
      const std::string prefix = "Bearer ";
      if (Open(req) ||
          (header.rfind(prefix, 0) == 0 && SameToken(header.substr(prefix.size()), options.token)) ||
          CookieHoldsToken(req.get_header_value("Cookie"), options.token)) {
        return httplib::Server::HandlerResponse::Unhandled;
      }
      res.set_header("WWW-Authenticate", "Bearer");
      ReplyError(res, 401, "Authorization",
                 header.empty() ? "no token: send the header 'Authorization: Bearer TOKEN' (the "
                                  "token is in the server's state folder, file token)"
                                : "wrong token");
      return httplib::Server::HandlerResponse::Handled;
    });
    server.set_exception_handler(
        [](const httplib::Request& req, httplib::Response& res, std::exception_ptr error) {
          std::string message = "unknown error";
          try {
            std::rethrow_exception(error);
          } catch (const std::exception& e) {
            message = e.what();
          } catch (...) {
          }
          spdlog::error("{} {}: {}", req.method, req.path, message);
          ReplyError(res, 500, "", message);
        });
    // Answers httplib makes itself (no route: 404; too large: 413) get a
    // JSON body too.
    server.set_error_handler(httplib::Server::HandlerWithResponse(
        [](const httplib::Request& req, httplib::Response& res) {
      if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
      if (res.status == 413) {
        ReplyError(res, 413, "body", "the request body is larger than the server accepts (--max-body)");
      } else if (res.status == 404) {
        ReplyError(res, 404, "", fmt::format("{} {}: no such resource (docs/openapi.yaml lists them)",
                                             req.method, req.path));
      } else {
        ReplyError(res, res.status, "", fmt::format("{} {}: the request cannot be answered (HTTP {})",
                                                    req.method, req.path, res.status));
      }
      return httplib::Server::HandlerResponse::Handled;
    }));

    const std::string jobs = "/api/v1/jobs";
    const std::string job = jobs + "/" + kName;
    server.Get("/", [](const httplib::Request&, httplib::Response& res) {
      const std::string_view page = DashboardPage();
      res.set_header("Content-Security-Policy",
                     "default-src 'self'; script-src 'self' 'unsafe-inline'; style-src 'unsafe-inline'");
      res.set_content(page.data(), page.size(), "text/html; charset=utf-8");
    });
    server.Get("/dashboard/chart.umd.js", [](const httplib::Request&, httplib::Response& res) {
      const std::string_view js = DashboardChartJs();
      res.set_content(js.data(), js.size(), "text/javascript; charset=utf-8");
    });
    // The dashboard's sign-in: the token once, then an HttpOnly, SameSite
    // Strict cookie that the browser sends with every request of the page.
    server.Post("/api/v1/session", Guarded([this](const httplib::Request& req, httplib::Response& res) {
                  const nlohmann::json body = BodyJson(req);
                  if (!body.is_object() || !body.contains("token") || !body["token"].is_string()) {
                    throw ServiceError(400, "token", "token: missing (the server's token, a string)");
                  }
                  if (!SameToken(body["token"].get<std::string>(), options.token)) {
                    throw ServiceError(401, "token", "wrong token");
                  }
                  res.set_header("Set-Cookie", fmt::format("{}={}; HttpOnly; SameSite=Strict; Path=/",
                                                           kCookie, options.token));
                  Reply(res, 200, {{"signed_in", true}});
                }));
    server.Get("/api/v1/health", Guarded([](const httplib::Request&, httplib::Response& res) {
                 Reply(res, 200, {{"status", "ok"}});
               }));
    server.Get("/api/v1/openapi.yaml", Guarded([](const httplib::Request&, httplib::Response& res) {
                 res.set_content(OpenApiYaml(), "application/yaml");
               }));
    server.Get(jobs, Guarded([this](const httplib::Request&, httplib::Response& res) {
                 Reply(res, 200, service.List());
               }));
    server.Post(jobs, Guarded([this](const httplib::Request& req, httplib::Response& res) {
                  Reply(res, 201, service.Submit(BodyJson(req)));
                }));
    server.Get(job, Guarded([this](const httplib::Request& req, httplib::Response& res) {
                 Reply(res, 200, service.Status(req.matches[1]));
               }));
    server.Delete(job, Guarded([this](const httplib::Request& req, httplib::Response& res) {
                    Reply(res, 200, service.Delete(req.matches[1]));
                  }));
    server.Post(job + "/cancel", Guarded([this](const httplib::Request& req, httplib::Response& res) {
                  Reply(res, 200, service.Cancel(req.matches[1]));
                }));
    server.Post(job + "/resume", Guarded([this](const httplib::Request& req, httplib::Response& res) {
                  Reply(res, 200, service.Resume(req.matches[1]));
                }));
    server.Post(job + "/budget", Guarded([this](const httplib::Request& req, httplib::Response& res) {
                  Reply(res, 200, service.ExtendBudget(req.matches[1], BodyJson(req)));
                }));
    server.Get(job + "/results", Guarded([this](const httplib::Request& req, httplib::Response& res) {
                 Reply(res, 200, service.Results(req.matches[1]));
               }));
    server.Get(job + "/best", Guarded([this](const httplib::Request& req, httplib::Response& res) {
                 Reply(res, 200, service.Best(req.matches[1]));
               }));
    server.Get(job + "/artefacts", Guarded([this](const httplib::Request& req, httplib::Response& res) {
                 Reply(res, 200, service.Artefacts(req.matches[1]));
               }));
    server.Get(job + "/artefacts/(.+)",
               Guarded([this](const httplib::Request& req, httplib::Response& res) {
                 const std::filesystem::path file = service.Artefact(req.matches[1], req.matches[2]);
                 if (file.extension() == ".html") {
                   // A report page (a job's, a loop's, a comparison's) is
                   // shown in the dashboard: its own images and styles, no
                   // script, framed only by the dashboard.
                   res.set_header("Content-Security-Policy",
                                  "default-src 'none'; img-src 'self' data:; style-src 'unsafe-inline'; "
                                  "frame-ancestors 'self'");
                 }
                 res.set_content(ReadFile(file), ContentType(file).c_str());
               }));
  }
};

HttpApi::HttpApi(JobService& service, HttpOptions options)
    : impl_(std::make_unique<Impl>(service, std::move(options))) {}

HttpApi::~HttpApi() = default;

int HttpApi::Bind() {
  const HttpOptions& o = impl_->options;
  const int port = o.port == 0 ? impl_->server.bind_to_any_port(o.listen)
                               : (impl_->server.bind_to_port(o.listen, o.port) ? o.port : -1);
  if (port <= 0) {
    throw std::runtime_error(fmt::format("cannot listen on {}:{} (in use, or not an address of "
                                         "this machine)",
                                         o.listen, o.port));
  }
  return port;
}

void HttpApi::Serve() { impl_->server.listen_after_bind(); }

void HttpApi::Stop() { impl_->server.stop(); }

}  // namespace calib::service
