// OutputVerifier: what a viewer, the web bridge and a lockstep capture take of the server's output
// under its key. Refused by reason: unsigned, bad signature, replayed (an out_seq not after the
// last one taken of the same run, or an earlier run played back); a restart (new epoch, later
// utime) is taken; meshes and status are ordered apart.
#include <gtest/gtest.h>

#include "vd/common/auth.h"
#include "vd/common/output_auth.h"

namespace vd {
namespace {

const std::string kKey(32, '\x71');

vdeform::mesh_t Mesh(int64_t epoch, int64_t out_seq, int64_t utime, const std::string& key = kKey) {
  vdeform::mesh_t m{};
  m.utime = utime;
  m.seq = 3;
  m.kind = vdeform::mesh_t::KIND_LIVE;
  m.encoding = vdeform::mesh_t::ENCODING_DRACO;
  m.epoch = epoch;
  m.out_seq = out_seq;
  if (!key.empty()) {
    EXPECT_TRUE(SignMesh(key, &m).ok());
  }
  return m;
}

vdeform::server_status_t StatusMsg(int64_t epoch, int64_t out_seq, int64_t utime, const std::string& key = kKey) {
  vdeform::server_status_t s{};
  s.utime = utime;
  s.state = vdeform::server_status_t::STATE_TRACKING;
  s.last_processed_seq = 3;
  s.epoch = epoch;
  s.out_seq = out_seq;
  if (!key.empty()) {
    EXPECT_TRUE(SignStatus(key, &s).ok());
  }
  return s;
}

TEST(OutputVerifierTest, TakesSignedOutputInOrderAndRefusesTheRestByReason) {
  OutputVerifier v(kKey);
  EXPECT_TRUE(v.Check(Mesh(5, 1, 1000)).ok());
  EXPECT_TRUE(v.Check(Mesh(5, 3, 1000)).ok()) << "gaps are fine (a dropped message)";
  const OutputCheck unsigned_mesh = v.Check(Mesh(5, 4, 1000, ""));
  EXPECT_EQ(unsigned_mesh.verdict, OutputVerdict::kUnsigned);
  EXPECT_EQ(unsigned_mesh.status.code(), StatusCode::kPermissionDenied);
  EXPECT_NE(unsigned_mesh.status.message().find("unsigned mesh"), std::string::npos) << unsigned_mesh.status.message();
  EXPECT_EQ(v.Check(Mesh(5, 4, 1000, std::string(32, '\x72'))).verdict, OutputVerdict::kBadSignature);
  vdeform::mesh_t forged = Mesh(5, 4, 1000);
  forged.seq = 99;
  EXPECT_EQ(v.Check(forged).verdict, OutputVerdict::kBadSignature) << "changed after signing";
  // A real one replayed: the same out_seq, and an older one.
  const OutputCheck replay = v.Check(Mesh(5, 3, 1000));
  EXPECT_EQ(replay.verdict, OutputVerdict::kReplayed);
  EXPECT_EQ(replay.status.code(), StatusCode::kPermissionDenied);
  EXPECT_NE(replay.status.message().find("out_seq 3 is not after 3"), std::string::npos) << replay.status.message();
  EXPECT_FALSE(v.Check(Mesh(5, 2, 1000)).ok());
  EXPECT_EQ(v.mesh_refused().unsigned_messages, 1);
  EXPECT_EQ(v.mesh_refused().bad_signature, 2);
  EXPECT_EQ(v.mesh_refused().replayed, 2);
  EXPECT_EQ(v.mesh_refused().total(), 5);
  EXPECT_EQ(v.mesh_refused().ToString(), "1 unsigned, 2 bad signature, 2 replayed");
  EXPECT_EQ(v.status_refused().total(), 0);
  EXPECT_TRUE(v.Check(Mesh(5, 4, 1000)).ok()) << "the refusals moved nothing";
}

TEST(OutputVerifierTest, ARestartIsANewEpochAndAnEarlierRunIsAReplay) {
  OutputVerifier v(kKey);
  ASSERT_TRUE(v.Check(StatusMsg(5, 40, 2000)).ok());
  // The server restarted: a new epoch, its count from 1 again, a later utime.
  EXPECT_TRUE(v.Check(StatusMsg(9, 1, 2500)).ok());
  EXPECT_TRUE(v.Check(StatusMsg(9, 2, 2600)).ok());
  // The earlier run played back, even with a higher out_seq: its utime is not after the last.
  const OutputCheck earlier = v.Check(StatusMsg(5, 41, 2100));
  EXPECT_EQ(earlier.verdict, OutputVerdict::kReplayed);
  EXPECT_NE(earlier.status.message().find("earlier server run"), std::string::npos) << earlier.status.message();
  EXPECT_EQ(v.status_refused().replayed, 1);
  // ... and it did not become the current run: the real one goes on.
  EXPECT_TRUE(v.Check(StatusMsg(9, 3, 2700)).ok());
  EXPECT_FALSE(v.Check(StatusMsg(9, 3, 2700)).ok());
}

TEST(OutputVerifierTest, MeshesAndStatusAreOrderedApart) {
  // One counter numbers both kinds; they arrive on separate channels, in either order.
  OutputVerifier v(kKey);
  EXPECT_TRUE(v.Check(StatusMsg(5, 11, 1000)).ok());
  EXPECT_TRUE(v.Check(Mesh(5, 10, 1000)).ok());
  EXPECT_TRUE(v.Check(StatusMsg(5, 12, 1000)).ok());
  EXPECT_EQ(v.mesh_refused().total() + v.status_refused().total(), 0);
}

}  // namespace
}  // namespace vd
