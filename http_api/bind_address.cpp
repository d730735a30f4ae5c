#include "http_api/bind_address.hpp"

#include <charconv>
#include <stdexcept>

namespace dronetrack::http_api {

std::pair<std::string, int> parse_bind_address(const std::string& bind) {
  const auto colon = bind.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == bind.size()) {
    throw std::runtime_error("HTTP bind address '" + bind + "' is not HOST:PORT");
  }
  std::string host = bind.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') {
    host = host.substr(1, host.size() - 2);
  }
  const std::string port_text = bind.substr(colon + 1);
  int port = -1;
  const auto [end, ec] =
      std::from_chars(port_text.data(), port_text.data() + port_text.size(), port);
  if (ec != std::errc() || end != port_text.data() + port_text.size() || port < 0 || port > 65535) {
    throw std::runtime_error("HTTP bind address '" + bind + "': port must be 0..65535");
  }
  return {host, port};
}

}  // namespace dronetrack::http_api
