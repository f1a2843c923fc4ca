#include "vd/viewer/display.h"

#include <netdb.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

namespace vd {
namespace {

// Connects to a Unix socket and closes it again; true when something listens there.
bool UnixSocketAccepts(const std::string& path) {
  sockaddr_un addr{};
  if (path.size() >= sizeof(addr.sun_path)) return false;
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return false;
  const bool ok = ::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) == 0;
  ::close(fd);
  return ok;
}

bool TcpAccepts(const std::string& host, int port) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  if (::getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found) != 0) return false;
  bool ok = false;
  for (addrinfo* a = found; a != nullptr && !ok; a = a->ai_next) {
    const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) continue;
    ok = ::connect(fd, a->ai_addr, a->ai_addrlen) == 0;
    ::close(fd);
  }
  ::freeaddrinfo(found);
  return ok;
}

std::string Env(const char* name) {
  const char* value = std::getenv(name);
  return value != nullptr ? value : "";
}

}  // namespace

StatusOr<X11Display> ParseX11Display(const std::string& text) {
  const size_t colon = text.rfind(':');
  if (colon == std::string::npos || colon + 1 >= text.size())
    return InvalidArgument("DISPLAY = '" + text + "' is not [host]:number[.screen]");
  X11Display display;
  display.host = text.substr(0, colon);
  std::string number = text.substr(colon + 1);
  const size_t dot = number.find('.');
  if (dot != std::string::npos) number = number.substr(0, dot);
  if (number.empty() || number.size() > 5 || number.find_first_not_of("0123456789") != std::string::npos)
    return InvalidArgument("DISPLAY = '" + text + "' has no display number");
  display.number = std::atoi(number.c_str());
  return display;
}

Status CheckDisplay() {
  const std::string x11 = Env("DISPLAY");
  const std::string wayland = Env("WAYLAND_DISPLAY");
  if (x11.empty() && wayland.empty()) return FailedPrecondition("neither $DISPLAY nor $WAYLAND_DISPLAY is set");
  std::string why;
  if (!x11.empty()) {
    StatusOr<X11Display> display = ParseX11Display(x11);
    if (!display.ok()) {
      why = display.status().message();
    } else if (display->host.empty() || display->host == "unix") {
      const std::string path = "/tmp/.X11-unix/X" + std::to_string(display->number);
      if (UnixSocketAccepts(path)) return Status::Ok();
      why = "no X server accepts connections on " + path + " (DISPLAY=" + x11 + ")";
    } else {
      if (TcpAccepts(display->host, 6000 + display->number)) return Status::Ok();
      why = "no X server accepts connections at " + display->host + ":" + std::to_string(6000 + display->number) +
            " (DISPLAY=" + x11 + ")";
    }
  }
  if (!wayland.empty()) {
    const std::string path = wayland[0] == '/' ? wayland : Env("XDG_RUNTIME_DIR") + "/" + wayland;
    if (UnixSocketAccepts(path)) return Status::Ok();
    why += (why.empty() ? "" : "; ") + std::string("no Wayland compositor at ") + path;
  }
  return FailedPrecondition(why);
}

}  // namespace vd
