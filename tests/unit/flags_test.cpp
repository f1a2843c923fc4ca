// The one flag parser every program uses: bindings, defaults in --help, and errors that name the flag.
#include "vd/common/flags.h"

#include <optional>
#include <tuple>

#include <gtest/gtest.h>

namespace vd {
namespace {

struct Bound {
  std::string name = "tube";
  int level = 3;
  int64_t count = -1;
  float weight = 2.5f;
  double seconds = 10.0;
  bool fast = false;
  bool enabled = true;
  std::string mode = "a";
};

FlagParser MakeParser(Bound* b) {
  FlagParser f("usage: prog [flags]", "Exit status: 0 or 2.\n");
  f.Section("Input");
  f.Add("name", &b->name, "Scene name", "NAME");
  f.Add("level", &b->level, "Level");
  f.Add("count", &b->count, "Count", "N");
  f.Section("Tuning");
  f.Add("weight", &b->weight, "Weight");
  f.Add("seconds", &b->seconds, "Seconds", "S");
  f.AddSwitch("fast", &b->fast, "Go fast");
  f.AddNegation("no-thing", &b->enabled, "Turn the thing off");
  f.AddCustom("mode", "M", "a", "a or b", [b](const std::string& v) {
    if (v != "a" && v != "b") return InvalidArgument("--mode expects a or b, got '" + v + "'");
    b->mode = v;
    return Status::Ok();
  });
  return f;
}

Status ParseInto(Bound* b, const std::vector<std::string>& args, bool* help = nullptr) {
  FlagParser f = MakeParser(b);
  bool h = false;
  Status s = f.Parse(args, &h);
  if (help) *help = h;
  return s;
}

TEST(FlagParserTest, SetsEveryKindOfField) {
  Bound b;
  FlagParser f = MakeParser(&b);
  bool help = true;
  ASSERT_TRUE(f.Parse({"--name", "cloth", "--level=5", "--count", "-7", "--weight", "0.25", "--seconds=1e-3", "--fast",
                       "--no-thing", "--mode", "b"},
                      &help)
                  .ok());
  EXPECT_FALSE(help);
  EXPECT_EQ(b.name, "cloth");
  EXPECT_EQ(b.level, 5);
  EXPECT_EQ(b.count, -7);
  EXPECT_FLOAT_EQ(b.weight, 0.25f);
  EXPECT_DOUBLE_EQ(b.seconds, 1e-3);
  EXPECT_TRUE(b.fast);
  EXPECT_FALSE(b.enabled);
  EXPECT_EQ(b.mode, "b");
  EXPECT_TRUE(f.Given("level"));
  EXPECT_TRUE(f.Given("no-thing"));
  EXPECT_FALSE(f.Given("bogus"));
}

TEST(FlagParserTest, UntouchedFieldsKeepTheirDefaults) {
  Bound b;
  ASSERT_TRUE(ParseInto(&b, {"--fast"}).ok());
  const Bound d;
  EXPECT_EQ(b.name, d.name);
  EXPECT_EQ(b.level, d.level);
  EXPECT_EQ(b.count, d.count);
  EXPECT_EQ(b.weight, d.weight);
  EXPECT_TRUE(b.enabled);
}

TEST(FlagParserTest, HelpShowsTheBoundDefaultsBySection) {
  Bound b;
  // The default is whatever the field holds when it is bound: one source.
  b.level = 9;
  const std::string help = MakeParser(&b).Help();
  EXPECT_EQ(help.find("usage: prog [flags]"), 0u);
  EXPECT_NE(help.find("\nInput:\n  --name NAME\n      Scene name (default: tube)\n"), std::string::npos) << help;
  EXPECT_NE(help.find("  --level VALUE\n      Level (default: 9)\n"), std::string::npos) << help;
  EXPECT_NE(help.find("\nTuning:\n  --weight VALUE\n      Weight (default: 2.5)\n"), std::string::npos) << help;
  EXPECT_NE(help.find("  --fast\n      Go fast\n"), std::string::npos) << help;
  EXPECT_NE(help.find("  --mode M\n      a or b (default: a)\n"), std::string::npos) << help;
  EXPECT_NE(help.find("  --help, -h\n"), std::string::npos);
  EXPECT_NE(help.find("Exit status: 0 or 2.\n"), std::string::npos);
  EXPECT_LT(help.find("Exit status"), help.size());
}

TEST(FlagParserTest, LongHelpIsWrapped) {
  Bound b;
  FlagParser f("u");
  f.Add("name", &b.name, std::string(30, 'a') + " " + std::string(40, 'b') + " " + std::string(40, 'c'));
  const std::string help = f.Help();
  EXPECT_NE(help.find("      " + std::string(30, 'a') + " " + std::string(40, 'b') + "\n      " + std::string(40, 'c')),
            std::string::npos)
      << help;
}

TEST(FlagParserTest, HelpStopsParsing) {
  Bound b;
  bool help = false;
  ASSERT_TRUE(ParseInto(&b, {"--level", "4", "-h", "--bogus"}, &help).ok());
  EXPECT_TRUE(help);
}

TEST(FlagParserTest, ErrorsNameTheFlag) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--bogus"}, "unknown flag --bogus"},
      {{"stray"}, "unexpected argument 'stray'"},
      {{"--"}, "unexpected argument '--'"},
      {{"--level"}, "--level needs a value"},
      {{"--level", "x"}, "--level expects an integer, got 'x'"},
      {{"--level", "4.5"}, "--level expects an integer"},
      {{"--level", "3000000000"}, "--level = 3000000000 is out of range"},
      {{"--count", "99999999999999999999"}, "--count expects an integer"},
      {{"--weight", "abc"}, "--weight expects a number, got 'abc'"},
      {{"--weight", "1e39"}, "--weight = 1e39 is out of range"},
      {{"--seconds", "nan"}, "--seconds expects a number"},
      {{"--seconds", "inf"}, "--seconds expects a number"},
      {{"--seconds", ""}, "--seconds expects a number"},
      {{"--fast=yes"}, "--fast takes no value"},
      {{"--mode", "c"}, "--mode expects a or b, got 'c'"},
  };
  for (const auto& [args, expected] : cases) {
    Bound b;
    const Status s = ParseInto(&b, args);
    ASSERT_FALSE(s.ok()) << args[0];
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
    EXPECT_NE(s.message().find(expected), std::string::npos) << s.message();
  }
}

TEST(FlagParserTest, CommandLineExitCodes) {
  auto run = [](std::vector<std::string> args, Status verdict) {
    Bound b;
    FlagParser f = MakeParser(&b);
    std::vector<char*> argv = {const_cast<char*>("prog")};
    for (std::string& a : args) argv.push_back(a.data());
    testing::internal::CaptureStderr();
    testing::internal::CaptureStdout();
    const std::optional<int> rc = f.ParseCommandLine(int(argv.size()), argv.data(), "prog", [&] { return verdict; });
    const std::string out = testing::internal::GetCapturedStdout(), err = testing::internal::GetCapturedStderr();
    return std::make_tuple(rc, out, err);
  };
  auto [rc_go, out_go, err_go] = run({"--fast"}, Status::Ok());
  EXPECT_FALSE(rc_go.has_value());
  EXPECT_EQ(out_go + err_go, "");
  auto [rc_help, out_help, err_help] = run({"--help"}, InvalidArgument("not checked on --help"));
  EXPECT_EQ(rc_help, 0);
  EXPECT_EQ(out_help.find("usage: prog"), 0u);
  EXPECT_EQ(err_help, "");
  auto [rc_bad, out_bad, err_bad] = run({"--level", "x"}, Status::Ok());
  EXPECT_EQ(rc_bad, 2);
  EXPECT_EQ(err_bad, "prog: --level expects an integer, got 'x'\n");
  auto [rc_invalid, out_invalid, err_invalid] = run({}, InvalidArgument("--fast and --slow exclude each other"));
  EXPECT_EQ(rc_invalid, 2);
  EXPECT_EQ(err_invalid, "prog: --fast and --slow exclude each other\n");
}

TEST(FlagParserTest, ParamOutOfBoundsNamesOwnerFieldValueAndBound) {
  EXPECT_EQ(ParamOutOfBounds("EngineParams", "voxel_size", 0.5, "<= 0.1 m").message(),
            "EngineParams.voxel_size = 0.5 violates <= 0.1 m");
}

}  // namespace
}  // namespace vd
