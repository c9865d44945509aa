// Whether an address names this machine's loopback: what the coordinator checks of the addresses
// it listens on (without tokens it serves loopback only) and of the Host a request to an open
// dashboard names (DNS rebinding).
#pragma once

#include <cctype>
#include <string>

namespace irfarm {

// True for HOST or HOST:PORT where HOST is 127.0.0.0/8, ::1 (bracketed or not) or localhost (any
// case), and for unix: sockets.
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
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

}  // namespace irfarm
