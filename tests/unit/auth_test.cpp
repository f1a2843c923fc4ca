// HMAC-SHA256 of control commands: the RFC 4231 vectors, sign/verify, tampering, key files.
#include <sys/stat.h>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "vd/common/auth.h"

namespace vd {
namespace {

TEST(AuthTest, HmacMatchesRfc4231) {
  // RFC 4231 test case 2.
  EXPECT_EQ(ToHex(HmacSha256("Jefe", "what do ya want for nothing?")),
            "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843");
  // Test case 1: 20 bytes of 0x0b, "Hi There".
  EXPECT_EQ(ToHex(HmacSha256(std::string(20, '\x0b'), "Hi There")),
            "b0344c61d8db38535ca8afceaf0bf12b881dc200c9833da726e9376c2e32cff7");
  // FIPS 180-2: SHA-256("abc").
  EXPECT_EQ(ToHex(Sha256("abc", 3)), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

vdeform::control_t Command() {
  vdeform::control_t m{};
  m.utime = 1764633600000000;
  m.command = vdeform::control_t::COMMAND_SAVE_SNAPSHOT;
  m.path = "run1";
  m.sender = "tester";
  m.auth_size = 0;
  return m;
}

TEST(AuthTest, SignedCommandsVerifyAndAnyChangeIsCaught) {
  const std::string key = "0123456789abcdef0123";
  vdeform::control_t m = Command();
  EXPECT_EQ(VerifyControl(key, m).code(), StatusCode::kPermissionDenied) << "unsigned";
  SignControl(key, &m);
  ASSERT_EQ(m.auth_size, 32);
  EXPECT_TRUE(VerifyControl(key, m).ok());
  EXPECT_FALSE(VerifyControl(key + "x", m).ok()) << "another key";
  auto tampered = [&](auto change) {
    vdeform::control_t t = m;
    change(&t);
    return VerifyControl(key, t).ok();
  };
  EXPECT_FALSE(tampered([](vdeform::control_t* t) { t->path = "../etc"; }));
  EXPECT_FALSE(tampered([](vdeform::control_t* t) { t->command = vdeform::control_t::COMMAND_RESET; }));
  EXPECT_FALSE(tampered([](vdeform::control_t* t) { t->utime += 1; }));
  EXPECT_FALSE(tampered([](vdeform::control_t* t) { t->sender = "other"; }));
  EXPECT_FALSE(tampered([](vdeform::control_t* t) { t->auth[31] ^= 1; }));
  EXPECT_FALSE(tampered([](vdeform::control_t* t) {
    t->auth.pop_back();
    t->auth_size = 31;
  }));
  // Length prefixes: moving bytes between path and sender changes the MAC.
  vdeform::control_t a = Command(), b = Command();
  a.path = "ab";
  a.sender = "c";
  b.path = "a";
  b.sender = "bc";
  EXPECT_NE(ControlAuthBytes(a), ControlAuthBytes(b));
}

TEST(AuthTest, KeyFilesMustExistBePrivateAndLongEnough) {
  const std::string dir = testing::TempDir() + "/vd_auth_keys";
  std::filesystem::create_directories(dir);
  auto write = [&](const std::string& name, const std::string& text, mode_t mode) {
    const std::string p = dir + "/" + name;
    std::ofstream(p, std::ios::binary | std::ios::trunc) << text;
    chmod(p.c_str(), mode);
    return p;
  };
  EXPECT_EQ(ReadControlKey(dir + "/missing").status().code(), StatusCode::kNotFound);
  EXPECT_EQ(ReadControlKey(write("open", "0123456789abcdef\n", 0644)).status().code(), StatusCode::kPermissionDenied);
  EXPECT_EQ(ReadControlKey(write("short", "0123456789\n", 0600)).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(ReadControlKey(dir).status().code(), StatusCode::kInvalidArgument) << "a directory";
  auto key = ReadControlKey(write("good", "0123456789abcdef-key\n\n", 0600));
  ASSERT_TRUE(key.ok()) << key.status().ToString();
  EXPECT_EQ(*key, "0123456789abcdef-key") << "trailing newlines are not part of the key";
}

}  // namespace
}  // namespace vd
