#pragma once
// A request the service refuses: the HTTP status it answers with (4xx), the
// request field at fault ("spec", "priority", "path", "name"; empty when it
// is the request as a whole) and a message naming the field, value and rule
// (for a bad spec, the same message `calib run` gives).

#include <stdexcept>
#include <string>

namespace calib::service {

class ServiceError : public std::runtime_error {
 public:
  ServiceError(int status, std::string field, const std::string& message)
      : std::runtime_error(message), status_(status), field_(std::move(field)) {}
  int status() const { return status_; }
  const std::string& field() const { return field_; }

 private:
  int status_;
  std::string field_;
};

}  // namespace calib::service
