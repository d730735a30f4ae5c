#pragma once
// HOST:PORT as the HTTP options take it ("127.0.0.1:8080", "[::1]:0", "0.0.0.0:80"). Parsed in
// one place so the command line can refuse a bad address (exit 2) before anything starts.
#include <string>
#include <utility>

namespace dronetrack::http_api {

// {host, port}; throws std::runtime_error naming the address and what is wrong with it.
std::pair<std::string, int> parse_bind_address(const std::string& bind);

}  // namespace dronetrack::http_api
