#pragma once
// vdeform-web's command line: flags, defaults, validation and --help text. The server-side
// parameters live in WebServerOptions (their one home); the flags bind to them.
#include <optional>
#include <string>
#include <vector>

#include "vd/common/status.h"
#include "vd/viewer/web_server.h"

namespace vd {

struct WebOptions {
  // LCM URL; empty: $LCM_DEFAULT_URL, else vd::kDefaultLcmUrl (see ResolveLcmUrl).
  std::string lcm_url;
  // --stream NAME: forward only that stream ("" = the unnamed one); unset: every stream heard.
  std::optional<std::string> stream;
  // Address, port, client limit and write time-out of the HTTP/WebSocket server. Its token is
  // read from token_file by the program.
  WebServerOptions server;
  // A file holding the token every request must carry (mode 600); empty: no token.
  std::string token_file;
  // The server's output key file (--key-file): only meshes and status signed under it are
  // forwarded; empty: everything is.
  std::string key_file;
  // Folder with index.html and the vendored scripts; empty: next to the executable (web/), then
  // ../share/vdeform/web.
  std::string web_root;
  // No status line and no informational log lines.
  bool quiet = false;
  // --help was given: print WebHelpText() and exit 0.
  bool help = false;
  Status Validate() const;
};

StatusOr<WebOptions> ParseWebArgs(const std::vector<std::string>& args);
std::string WebHelpText();

// Where the page's files are: `flag` if given, else `exe_dir`/web, else
// `exe_dir`/../share/vdeform/web (the first that has an index.html).
StatusOr<std::string> FindWebRoot(const std::string& flag, const std::string& exe_dir);

}  // namespace vd
