#pragma once
// Which client a connection or request counts against for the per-client limits: an IPv4
// address (also when mapped into IPv6) as it is, an IPv6 address by its /64, since one host
// usually owns a whole /64 and could otherwise take a fresh address per request.
#include <string>

namespace dronetrack::http_api {

// `ip` as a numeric address ("192.0.2.7", "2001:db8::1", "::ffff:192.0.2.7"); anything that
// does not parse as one is returned as it is.
std::string client_address_key(const std::string& ip);

// True for 127.0.0.0/8, ::1, "localhost" and the IPv4-mapped loopback: an address only this
// machine can reach.
bool is_loopback_host(const std::string& host);

}  // namespace dronetrack::http_api
