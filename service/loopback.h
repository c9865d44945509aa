// Whether an address names this machine's loopback: what the coordinator checks of the addresses
// it listens on (without tokens it serves loopback only) and of the Host a request to an open
// dashboard names (DNS rebinding).
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>

#include <cctype>
#include <string>

namespace irfarm {

// True for HOST or HOST:PORT where HOST is an IPv4 address in 127.0.0.0/8, the IPv6 loopback
// (::1 in any spelling, bracketed or not; also ::ffff:127.x.y.z) or localhost (any case), and for
// unix: sockets. Addresses are parsed (inet_pton), not matched by prefix: "127.0.0.1.nip.io" and
// "127.evil.example" are names that resolve anywhere (an attacker's, rebound to 127.0.0.1).
inline bool IsLoopbackAddress(const std::string& address) {
  if (address.rfind("unix:", 0) == 0) return true;
  std::string host = address;
  if (!host.empty() && host.front() == '[') {
    const size_t close = host.find(']');
    host = close == std::string::npos ? "" : host.substr(1, close - 1);
  } else if (const size_t colon = host.rfind(':');
             colon != std::string::npos && host.find(':') == colon) {
    host.resize(colon);  // one colon: HOST:PORT (more: a bare IPv6 address)
  }
  for (char& c : host) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (host == "localhost") return true;
  in_addr v4;
  if (inet_pton(AF_INET, host.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6;
  if (inet_pton(AF_INET6, host.c_str(), &v6) == 1)
    return IN6_IS_ADDR_LOOPBACK(&v6) || (IN6_IS_ADDR_V4MAPPED(&v6) && v6.s6_addr[12] == 127);
  return false;
}

}  // namespace irfarm
