#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "vd/viewer/render.h"

namespace vd {
namespace {

// A UV sphere of `radius` around `centre`, normals outwards, coloured by latitude.
TriangleMesh Sphere(float cx, float cy, float cz, float radius, int rings = 16, int segments = 32) {
  TriangleMesh m;
  for (int r = 0; r <= rings; ++r) {
    const float theta = static_cast<float>(M_PI) * r / rings;
    for (int s = 0; s < segments; ++s) {
      const float phi = 2.f * static_cast<float>(M_PI) * s / segments;
      m.positions.insert(m.positions.end(), {cx + radius * std::sin(theta) * std::cos(phi), cy + radius * std::cos(theta),
                                             cz + radius * std::sin(theta) * std::sin(phi)});
      m.colors.insert(m.colors.end(), {static_cast<uint8_t>(255 * r / rings), 100, 50});
    }
  }
  for (int r = 0; r < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      const int a = r * segments + s, b = r * segments + (s + 1) % segments;
      const int c = a + segments, d = b + segments;
      m.triangles.insert(m.triangles.end(), {a, c, b, b, c, d});
    }
  return m;
}

// An axis-aligned square at depth z facing the camera, one colour.
void AddQuad(TriangleMesh* m, float x0, float y0, float x1, float y1, float z, uint8_t r, uint8_t g, uint8_t b) {
  const int base = static_cast<int>(m->num_vertices());
  m->positions.insert(m->positions.end(), {x0, y0, z, x1, y0, z, x1, y1, z, x0, y1, z});
  for (int k = 0; k < 4; ++k) m->colors.insert(m->colors.end(), {r, g, b});
  m->triangles.insert(m->triangles.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
}

int64_t NonBackground(const RenderResult& r, const RenderOptions& o) {
  int64_t n = 0;
  for (int y = 0; y < r.image.rows; ++y)
    for (int x = 0; x < r.image.cols; ++x) n += r.image.at<cv::Vec3b>(y, x) != o.background;
  return n;
}

TEST(RenderTest, SphereCoversAPlausibleDiscWithShading) {
  const TriangleMesh sphere = Sphere(0.05f, -0.02f, 1.0f, 0.2f);
  RenderOptions options;
  auto r = RenderMesh(sphere, sphere.colors, options);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->image.type(), CV_8UC3);
  ASSERT_EQ(r->image.cols, 640);
  ASSERT_EQ(r->image.rows, 480);
  EXPECT_EQ(r->eye_offset_z, 0.f);
  // Fitted to 90% of the height: a disc of diameter ~432 px covers pi/4 * 432^2 ~ 146k pixels.
  const double expected = M_PI / 4 * std::pow(480 * 0.9, 2);
  EXPECT_NEAR(static_cast<double>(r->covered_pixels), expected, 0.08 * expected);
  EXPECT_EQ(NonBackground(*r, options), r->covered_pixels);
  // Centred: the centre pixel is covered, the corners are not.
  EXPECT_GT(r->depth.at<float>(240, 320), 0.f);
  EXPECT_EQ(r->depth.at<float>(2, 2), 0.f);
  EXPECT_EQ(r->depth.at<float>(477, 637), 0.f);
  // Visible depth is the near side: around z = 1 - 0.2 at the centre, within the sphere's range.
  EXPECT_NEAR(r->depth.at<float>(240, 320), 0.8f, 0.01f);
  // Headlight: the centre faces the camera and is brighter than the rim.
  const cv::Vec3b centre = r->image.at<cv::Vec3b>(240, 320);
  int rim_x = 320;
  while (rim_x < 639 && r->depth.at<float>(240, rim_x + 1) > 0.f) ++rim_x;
  const cv::Vec3b rim = r->image.at<cv::Vec3b>(240, rim_x - 1);
  EXPECT_GT(centre[1], rim[1] + 30);
}

TEST(RenderTest, NearTriangleHidesFarOneWhateverTheDrawingOrder) {
  for (bool near_first : {true, false}) {
    TriangleMesh m;
    if (near_first) AddQuad(&m, -0.1f, -0.1f, 0.1f, 0.1f, 1.0f, 255, 0, 0);
    AddQuad(&m, -0.3f, -0.3f, 0.3f, 0.3f, 2.0f, 0, 255, 0);
    if (!near_first) AddQuad(&m, -0.1f, -0.1f, 0.1f, 0.1f, 1.0f, 255, 0, 0);
    RenderOptions options;
    options.ambient = 1.f;
    auto r = RenderMesh(m, m.colors, options);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    // Centre shows the red near quad (BGR), at depth 1.
    EXPECT_EQ(r->image.at<cv::Vec3b>(240, 320), cv::Vec3b(0, 0, 255)) << near_first;
    EXPECT_NEAR(r->depth.at<float>(240, 320), 1.0f, 1e-4f);
    // Away from the centre but inside the far quad: green, depth 2.
    EXPECT_EQ(r->image.at<cv::Vec3b>(240, 140), cv::Vec3b(0, 255, 0));
    EXPECT_NEAR(r->depth.at<float>(240, 140), 2.0f, 1e-4f);
    // The far quad spans 0.3/2 = 0.15 rad each way, the near one 0.1: the near one covers
    // (0.1/0.15)^2 = 44% of the far one's area.
    int red = 0, green = 0;
    for (int y = 0; y < 480; ++y)
      for (int x = 0; x < 640; ++x) {
        const cv::Vec3b px = r->image.at<cv::Vec3b>(y, x);
        red += px == cv::Vec3b(0, 0, 255);
        green += px == cv::Vec3b(0, 255, 0);
      }
    EXPECT_NEAR(static_cast<double>(red) / (red + green), 4.0 / 9.0, 0.02);
  }
}

TEST(RenderTest, ViewFromLiveCameraKeepsImageOrientation) {
  // Camera coordinates: x right, y down. A red quad on the right must appear on the right.
  TriangleMesh m;
  AddQuad(&m, 0.1f, -0.1f, 0.3f, 0.1f, 1.0f, 255, 0, 0);
  AddQuad(&m, -0.3f, -0.1f, -0.1f, 0.1f, 1.0f, 0, 0, 255);
  AddQuad(&m, -0.05f, 0.2f, 0.05f, 0.3f, 1.0f, 0, 255, 0);
  RenderOptions options;
  options.ambient = 1.f;
  auto r = RenderMesh(m, m.colors, options);
  ASSERT_TRUE(r.ok());
  double red_x = 0, blue_x = 0, green_y = 0, red_y = 0;
  int red = 0, blue = 0, green = 0;
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x) {
      const cv::Vec3b px = r->image.at<cv::Vec3b>(y, x);
      if (px == cv::Vec3b(0, 0, 255)) red_x += x, red_y += y, ++red;
      if (px == cv::Vec3b(255, 0, 0)) blue_x += x, ++blue;
      if (px == cv::Vec3b(0, 255, 0)) green_y += y, ++green;
    }
  ASSERT_GT(red, 100);
  ASSERT_GT(blue, 100);
  ASSERT_GT(green, 100);
  EXPECT_GT(red_x / red, blue_x / blue + 200);
  EXPECT_GT(green_y / green, red_y / red + 100);
}

TEST(RenderTest, MeshAroundTheOriginIsSeenFromFurtherBack) {
  const TriangleMesh sphere = Sphere(0.f, 0.f, 0.f, 0.5f);
  RenderOptions options;
  options.width = 200;
  options.height = 200;
  auto r = RenderMesh(sphere, {}, options);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_GT(r->eye_offset_z, 0.5f);
  EXPECT_GT(r->covered_pixels, 200 * 200 / 2);
  // No colour: uniform grey, shaded.
  const cv::Vec3b centre = r->image.at<cv::Vec3b>(100, 100);
  EXPECT_EQ(centre[0], centre[1]);
  EXPECT_GT(centre[0], 150);
}

TEST(RenderTest, OrbitAndZoomChangeTheImage) {
  TriangleMesh m;
  AddQuad(&m, -0.2f, -0.2f, 0.2f, 0.2f, 1.0f, 200, 200, 200);
  RenderOptions options;
  auto front = RenderMesh(m, {}, options);
  ViewParams side;
  side.yaw = 1.2f;
  auto turned = RenderMesh(m, {}, options, side);
  ViewParams zoomed;
  zoomed.zoom = 0.5f;
  auto small = RenderMesh(m, {}, options, zoomed);
  ASSERT_TRUE(front.ok() && turned.ok() && small.ok());
  // Zoom 0.5 halves the size: a quarter of the area.
  EXPECT_NEAR(static_cast<double>(small->covered_pixels) / front->covered_pixels, 0.25, 0.02);
  // Turned by 1.2 rad and refitted, the quad keeps its height but its shading drops with cos.
  EXPECT_GT(turned->covered_pixels, 1000);
  EXPECT_LT(turned->image.at<cv::Vec3b>(240, 320)[0], front->image.at<cv::Vec3b>(240, 320)[0] - 50);
}

TEST(RenderTest, EmptyMeshGivesBackgroundAndBadInputIsRefused) {
  RenderOptions options;
  auto empty = RenderMesh(TriangleMesh{}, {}, options);
  ASSERT_TRUE(empty.ok());
  EXPECT_EQ(empty->covered_pixels, 0);
  EXPECT_EQ(NonBackground(*empty, options), 0);

  TriangleMesh bad;
  AddQuad(&bad, 0, 0, 1, 1, 1, 1, 2, 3);
  bad.triangles[4] = 99;
  EXPECT_FALSE(RenderMesh(bad, {}, options).ok());
  TriangleMesh ok;
  AddQuad(&ok, 0, 0, 1, 1, 1, 1, 2, 3);
  EXPECT_FALSE(RenderMesh(ok, std::vector<uint8_t>(5), options).ok());
  ok.positions[2] = NAN;
  EXPECT_FALSE(RenderMesh(ok, {}, options).ok());
  RenderOptions tiny;
  tiny.width = 4;
  EXPECT_FALSE(tiny.Validate().ok());
  EXPECT_NE(tiny.Validate().message().find("width"), std::string::npos);
  ViewParams nan_zoom;
  nan_zoom.zoom = NAN;
  TriangleMesh quad;
  AddQuad(&quad, 0, 0, 1, 1, 1, 1, 2, 3);
  EXPECT_FALSE(RenderMesh(quad, {}, options, nan_zoom).ok());
}

TEST(RenderTest, VerticesFarOffScreenDoNotCrash) {
  // One huge triangle reaching far outside the image after a strong zoom.
  TriangleMesh m;
  AddQuad(&m, -0.2f, -0.2f, 0.2f, 0.2f, 1.0f, 10, 20, 30);
  m.positions.insert(m.positions.end(), {-1e4f, -1e4f, 1.0f, 1e4f, -1e4f, 1.0f, 0.f, 1e4f, 1.0f});
  m.triangles.insert(m.triangles.end(), {4, 5, 6});
  m.colors.clear();
  ViewParams view;
  view.zoom = 1000.f;
  auto r = RenderMesh(m, {}, RenderOptions{}, view);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->covered_pixels, 640 * 480);
}

TEST(CanonicalColorsTest, MapsPositionsToTheBoundingBox) {
  TriangleMesh canonical;
  canonical.positions = {0.f, -1.f, 2.f, 1.f, 1.f, 4.f, 0.5f, 0.f, 3.f, 0.f, -1.f, 2.f};
  canonical.triangles = {0, 1, 2};
  const std::vector<uint8_t> rgb = CanonicalColors(canonical);
  ASSERT_EQ(rgb.size(), 12u);
  EXPECT_EQ(std::vector<uint8_t>(rgb.begin(), rgb.begin() + 3), (std::vector<uint8_t>{0, 0, 0}));
  EXPECT_EQ(std::vector<uint8_t>(rgb.begin() + 3, rgb.begin() + 6), (std::vector<uint8_t>{255, 255, 255}));
  EXPECT_EQ(std::vector<uint8_t>(rgb.begin() + 6, rgb.begin() + 9), (std::vector<uint8_t>{128, 128, 128}));
  // Identical canonical positions get identical colours.
  EXPECT_EQ(std::vector<uint8_t>(rgb.begin() + 9, rgb.end()), std::vector<uint8_t>(rgb.begin(), rgb.begin() + 3));
  // A flat axis maps to the middle.
  TriangleMesh flat = canonical;
  for (size_t i = 2; i < flat.positions.size(); i += 3) flat.positions[i] = 7.f;
  const std::vector<uint8_t> flat_rgb = CanonicalColors(flat);
  for (size_t i = 2; i < flat_rgb.size(); i += 3) EXPECT_EQ(flat_rgb[i], 128);
}

TEST(CanonicalColorsTest, SameCanonicalPointSameColourWhereverItMovedLive) {
  // Two live vertices far apart whose canonical positions coincide render in the same colour,
  // and unlike two vertices that are close live but apart in the canonical pose.
  TriangleMesh live;
  AddQuad(&live, -0.3f, -0.1f, -0.1f, 0.1f, 1.0f, 9, 9, 9);
  AddQuad(&live, 0.1f, -0.1f, 0.3f, 0.1f, 1.0f, 9, 9, 9);
  TriangleMesh canonical = live;
  for (int v = 4; v < 8; ++v)
    for (int a = 0; a < 3; ++a) canonical.positions[3 * v + a] = live.positions[3 * (v - 4) + a];
  const VertexColors colors = SelectVertexColors(live, 7, &canonical, 7, ColorMode::kCanonical);
  ASSERT_EQ(colors.used, ColorMode::kCanonical);
  for (int v = 0; v < 4; ++v)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(colors.rgb[3 * v + c], colors.rgb[3 * (v + 4) + c]);
  // Corners 0 and 2 of a quad differ in canonical x and y, so the colours do vary.
  EXPECT_NE(colors.rgb[0], colors.rgb[6]);
  RenderOptions options;
  options.ambient = 1.f;
  auto r = RenderMesh(live, colors.rgb, options);
  ASSERT_TRUE(r.ok());
  // The same point of each quad (a quarter in from its low corner) is drawn at two places in one colour.
  const Intrinsics& k = r->intrinsics;
  auto pixel = [&](float x, float y) {
    return r->image.at<cv::Vec3b>(static_cast<int>(k.fy * y + k.cy), static_cast<int>(k.fx * x + k.cx));
  };
  const cv::Vec3b left = pixel(-0.25f, -0.05f);
  const cv::Vec3b right = pixel(0.15f, -0.05f);
  EXPECT_NE(left, options.background);
  EXPECT_LE(cv::norm(left, right, cv::NORM_INF), 2.0);
}

TEST(CanonicalColorsTest, ALiveMeshCarryingItsCanonicalPositionsNeedsNoCanonicalMesh) {
  TriangleMesh live;
  AddQuad(&live, 0, 0, 1, 1, 1, 10, 20, 30);
  TriangleMesh canonical = live;
  canonical.positions[0] = -5.f;
  live.canonical = canonical.positions;
  // No canonical mesh at all, or another frame's: the carried positions are used, as a canonical
  // mesh of the same frame would be.
  const VertexColors own = SelectVertexColors(live, 8, nullptr, -1, ColorMode::kCanonical);
  EXPECT_EQ(own.used, ColorMode::kCanonical);
  EXPECT_EQ(own.rgb, CanonicalColors(canonical));
  EXPECT_EQ(SelectVertexColors(live, 8, &live, 7, ColorMode::kCanonical).rgb, CanonicalColors(canonical));
  // Other modes ignore them.
  EXPECT_EQ(SelectVertexColors(live, 8, nullptr, -1, ColorMode::kVertex).rgb, live.colors);
}

TEST(CanonicalColorsTest, FallsBackWithoutAMatchingCanonicalMesh) {
  TriangleMesh live;
  AddQuad(&live, 0, 0, 1, 1, 1, 10, 20, 30);
  TriangleMesh canonical = live;
  canonical.positions[0] = -5.f;
  // Another frame's canonical mesh: the vertex order may differ, so the mesh colour is used.
  VertexColors other_seq = SelectVertexColors(live, 8, &canonical, 7, ColorMode::kCanonical);
  EXPECT_EQ(other_seq.used, ColorMode::kVertex);
  EXPECT_EQ(other_seq.rgb, live.colors);
  // Same seq but a different vertex count: not the same surface either.
  TriangleMesh smaller = canonical;
  smaller.positions.resize(9);
  smaller.triangles = {0, 1, 2};
  EXPECT_EQ(SelectVertexColors(live, 7, &smaller, 7, ColorMode::kCanonical).used, ColorMode::kVertex);
  EXPECT_EQ(SelectVertexColors(live, 7, nullptr, -1, ColorMode::kCanonical).used, ColorMode::kVertex);
  // A live mesh without colours falls back to grey shading.
  TriangleMesh plain = live;
  plain.colors.clear();
  VertexColors grey = SelectVertexColors(plain, 7, nullptr, -1, ColorMode::kVertex);
  EXPECT_EQ(grey.used, ColorMode::kShade);
  EXPECT_TRUE(grey.rgb.empty());
  EXPECT_EQ(SelectVertexColors(live, 7, &canonical, 7, ColorMode::kShade).used, ColorMode::kShade);
  EXPECT_EQ(SelectVertexColors(live, 7, &canonical, 7, ColorMode::kCanonical).used, ColorMode::kCanonical);
}

TEST(ColorModeTest, ParseNameAndCycle) {
  for (ColorMode m : {ColorMode::kCanonical, ColorMode::kVertex, ColorMode::kShade}) {
    auto parsed = ParseColorMode(ColorModeName(m));
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(*parsed, m);
  }
  EXPECT_FALSE(ParseColorMode("rainbow").ok());
  EXPECT_EQ(NextColorMode(ColorMode::kCanonical), ColorMode::kVertex);
  EXPECT_EQ(NextColorMode(ColorMode::kVertex), ColorMode::kShade);
  EXPECT_EQ(NextColorMode(ColorMode::kShade), ColorMode::kCanonical);
}

}  // namespace
}  // namespace vd
