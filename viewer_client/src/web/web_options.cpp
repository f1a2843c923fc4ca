#include "vd/viewer/web_options.h"

#include <filesystem>

#include "vd/common/flags.h"
#include "vd/common/messages.h"

namespace vd {
namespace {

constexpr const char* kUsage = R"(vdeform-web: the web viewer. Subscribes to the meshes and status vdeform-server publishes over
LCM and serves a page that shows them in any browser (three.js; the mesh is sent as the Draco
bytes the server made and decoded in the browser).

Usage: vdeform-web [flags]      then open http://127.0.0.1:8080/ (with --token-file: /?token=TOKEN)

Read-only: the only thing a page can cause is a REQUEST_MESH, at most one a second in all. A page
that reads slowly gets only the newest mesh; a page's oversized or malformed message closes its
connection alone. Prints a status line (clients, meshes forwarded, bytes, the server's state).)";

constexpr const char* kEpilogue = R"(Binding another address than loopback without --token-file prints a warning: anyone who reaches
the port sees the reconstruction. docs/OPERATIONS.md ("The web viewer") shows a TLS reverse proxy.
SIGINT/SIGTERM end it cleanly: it closes every connection, prints a summary and exits 0.
Exit status: 0 done (signal), 1 run-time failure (LCM, the port, the web folder), 2 bad flags or key/token file.
)";

void Bind(FlagParser* f, WebOptions* o) {
  f->Add("lcm-url", &o->lcm_url,
         "LCM URL to listen on. Default: $LCM_DEFAULT_URL if set, else "
         "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304.",
         "URL");
  f->AddCustom("stream", "NAME", "every stream",
               "Forward only the stream NAME (channels VDEFORM_<NAME>_MESH, _STATUS, _CONTROL; '' = the unnamed "
               "VDEFORM_MESH ...). Default: every stream heard; the page lists them and switches between them.",
               [o](const std::string& v) {
                 VD_RETURN_IF_ERROR(ValidateStreamName(v).WithContext("--stream"));
                 o->stream = v;
                 return Status::Ok();
               });
  f->Add("bind", &o->server.bind, "Address the page is served on (loopback keeps it on this host; 0.0.0.0: all).",
         "ADDR");
  f->Add("port", &o->server.port, "TCP port of the page and its WebSocket (0: any free port, printed at start).", "N");
  f->AddCustom("token-file", "FILE", "",
               "Require the token in FILE (16-256 characters of A-Z a-z 0-9 . _ ~ -, mode 600; e.g. openssl rand "
               "-hex 32) on every request: as ?token=, as 'Authorization: Bearer TOKEN', or as the cookie the page "
               "sets. A missing or wrong token gets 403.",
               [o](const std::string& v) {
                 if (v.empty()) return InvalidArgument("--token-file needs a file name");
                 o->token_file = v;
                 return Status::Ok();
               });
  f->AddCustom("key-file", "FILE", "",
               "The server's --output-key-file (one line KEY, 64 hex digits, mode 600): forward only meshes and "
               "status signed under it by the running server of each stream; unsigned, wrongly signed and replayed "
               "ones are counted (status line, summary) and dropped. Default: everything is forwarded.",
               [o](const std::string& v) {
                 if (v.empty()) return InvalidArgument("--key-file needs a file name");
                 o->key_file = v;
                 return Status::Ok();
               });
  f->Add("max-clients", &o->server.max_clients,
         "Browser connections (WebSockets) at once; one more gets 503. Plain HTTP connections (loading the page) "
         "have 16 more slots.",
         "N");
  f->Add("write-timeout", &o->server.write_timeout_s,
         "Close a page whose connection has not taken a message for this many seconds (a stalled reader).", "S");
  f->Add("web-root", &o->web_root,
         "Folder with the page's files (index.html, the vendored three.js and uPlot). Default: web/ beside the "
         "executable, else ../share/vdeform/web.",
         "DIR");
  f->AddSwitch("quiet", &o->quiet, "No status line and no informational messages.");
}

}  // namespace

Status WebOptions::Validate() const {
  // The token comes from the file later; the rest of the server options are checked here.
  WebServerOptions without_token = server;
  without_token.token.clear();
  return without_token.Validate().WithContext("bad flag");
}

StatusOr<WebOptions> ParseWebArgs(const std::vector<std::string>& args) {
  WebOptions options;
  FlagParser flags(kUsage, kEpilogue);
  Bind(&flags, &options);
  VD_RETURN_IF_ERROR(flags.Parse(args, &options.help));
  if (!options.help) VD_RETURN_IF_ERROR(options.Validate());
  return options;
}

std::string WebHelpText() {
  WebOptions defaults;
  FlagParser flags(kUsage, kEpilogue);
  Bind(&flags, &defaults);
  return flags.Help();
}

StatusOr<std::string> FindWebRoot(const std::string& flag, const std::string& exe_dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!flag.empty()) {
    if (!fs::exists(fs::path(flag) / "index.html", ec)) return NotFound("--web-root '" + flag + "' has no index.html");
    return flag;
  }
  const fs::path candidates[] = {fs::path(exe_dir) / "web", fs::path(exe_dir) / ".." / "share" / "vdeform" / "web"};
  for (const fs::path& dir : candidates)
    if (fs::exists(dir / "index.html", ec)) return dir.lexically_normal().string();
  return NotFound("no web folder with index.html beside the executable (" + candidates[0].string() + ") or in " +
                  candidates[1].lexically_normal().string() + "; build the target vdeform-web or give --web-root");
}

}  // namespace vd
