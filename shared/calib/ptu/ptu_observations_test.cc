#include "shared/calib/ptu/ptu_observations.h"

#include <gtest/gtest.h>

#include <cmath>

namespace idi::calib {
namespace {

constexpr const char* kPtuCsvHeader = "camera,x_mm,y_mm,z_mm,alpha_deg,beta_deg,gamma_deg,pan_deg,tilt_deg,u_px,v_px\n";

TEST(PtuObservationsCsv, RoundTripsExactly) {
  std::vector<PtuObservation> obs(2);
  obs[0].camera = BiclopsSide::kLeft;
  obs[0].tcf = {123.25, -456.5, 789.125, 0.1, 2.0, -0.3};
  obs[0].pan_rad = 0.7;
  obs[0].tilt_rad = -0.25;
  obs[0].pixel_px = Vec2d(101.37, 412.01);
  obs[1] = obs[0];
  obs[1].camera = BiclopsSide::kRight;
  obs[1].pixel_px = Vec2d(1e-3, 479.4999);
  const std::string text = FormatPtuObservationsCsv(obs);
  EXPECT_EQ(text.substr(0, text.find('\n') + 1), kPtuCsvHeader);
  const auto back = ParsePtuObservationsCsv(text, "t.csv");
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ASSERT_EQ(back->size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    const PtuObservation& a = obs[i];
    const PtuObservation& b = (*back)[i];
    EXPECT_EQ(a.camera, b.camera);
    EXPECT_DOUBLE_EQ(a.tcf.x_mm, b.tcf.x_mm);
    EXPECT_DOUBLE_EQ(a.tcf.beta_rad, b.tcf.beta_rad);
    EXPECT_DOUBLE_EQ(a.pan_rad, b.pan_rad);
    EXPECT_DOUBLE_EQ(a.tilt_rad, b.tilt_rad);
    EXPECT_EQ(a.pixel_px, b.pixel_px);
    EXPECT_EQ(b.source_line, static_cast<int>(i) + 2);
  }
}

TEST(PtuObservationsCsv, AcceptsColumnsInAnyOrderCommentsAndBlankLines) {
  const std::string text =
      "# acquired 2024-05-01\n"
      "u_px,v_px,camera,pan_deg,tilt_deg,x_mm,y_mm,z_mm,alpha_deg,beta_deg,gamma_deg\n"
      "\n"
      "10.5, 20.25, right, 90, -10, 1, 2, 3, 0, 45, 0\r\n";
  const auto r = ParsePtuObservationsCsv(text, "t.csv");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->size(), 1u);
  EXPECT_EQ((*r)[0].camera, BiclopsSide::kRight);
  EXPECT_EQ((*r)[0].pixel_px, Vec2d(10.5, 20.25));
  EXPECT_NEAR((*r)[0].pan_rad, kPi / 2, 1e-15);
  EXPECT_NEAR((*r)[0].tcf.beta_rad, kPi / 4, 1e-15);
  EXPECT_EQ((*r)[0].source_line, 4);
}

void ExpectPtuCsvError(const std::string& text, const std::string& fragment) {
  const auto r = ParsePtuObservationsCsv(text, "obs.csv");
  ASSERT_FALSE(r.ok()) << "expected an error containing '" << fragment << "'";
  EXPECT_NE(r.status().message().find(fragment), std::string::npos) << r.status().message();
}

TEST(PtuObservationsCsv, BadInputNamesTheFileLineAndColumn) {
  const std::string h = kPtuCsvHeader;
  ExpectPtuCsvError("", "obs.csv: no header");
  ExpectPtuCsvError("camera,x_mm\n", "lacks column 'y_mm'");
  ExpectPtuCsvError("camera,x_mm,y_mm,z_mm,alpha_deg,beta_deg,gamma_deg,pan_deg,tilt_deg,u_px,v_px,extra\n",
                    "unknown column 'extra'");
  ExpectPtuCsvError(h + "left,1,2,3,0,0,0,0,0,,\n", "obs.csv:2: u_px is empty: the spot was not found");
  ExpectPtuCsvError(h + "left,1,2,3,0,0,0,0,0,5\n", "obs.csv:2: 10 fields where the header has 11");
  ExpectPtuCsvError(h + "middle,1,2,3,0,0,0,0,0,5,5\n", "camera = 'middle'");
  ExpectPtuCsvError(h + "left,1,2,3,0,0,0,0,0,5,nan\n", "v_px = 'nan' is not finite");
  ExpectPtuCsvError(h + "left,1,2,3,0,0,0,0,0,5,inf\n", "v_px = 'inf' is not finite");
  ExpectPtuCsvError(h + "left,1,2,3,0,0,0,0,0,5,1e999\n", "v_px = '1e999' is not a number");
  ExpectPtuCsvError(h + "left,1,2,3x,0,0,0,0,0,5,5\n", "z_mm = '3x' is not a number");
  ExpectPtuCsvError(h + "left,1,2,3,0,0,0,0,0,5,5\nleft,1,2,\x01\xff,0,0,0,0,0,5,5\n", "obs.csv:3: z_mm");
}

TEST(PtuObservationsCheck, RangeAndDoubledSpots) {
  const std::string h = kPtuCsvHeader;
  auto parsed = ParsePtuObservationsCsv(h + "left,1,2,3,0,0,0,170,0,5,5\n", "obs.csv");
  ASSERT_TRUE(parsed.ok());
  Status st = CheckPtuObservations(*parsed, PtuRange{}, "obs.csv");
  EXPECT_EQ(st.code(), StatusCode::kOutOfRange);
  EXPECT_NE(st.message().find("obs.csv:2: pan = 170.0000 deg is outside the PTU's range"), std::string::npos)
      << st.message();
  // A reading at the end stop is in range even when its conversion from counts differs from the
  // limit's in the last bits; a hundredth of a degree beyond is not.
  const PtuRange range;
  EXPECT_TRUE(range.Contains(std::nextafter(range.pan_min_rad, -1.0), 0.0));
  EXPECT_TRUE(range.Contains(range.pan_max_rad * (1 + 1e-15), range.tilt_max_rad * (1 + 1e-15)));
  EXPECT_FALSE(range.Contains(range.pan_max_rad + DegToRad(0.01), 0.0));
  EXPECT_FALSE(range.Contains(0.0, range.tilt_min_rad - DegToRad(0.01)));
  parsed = ParsePtuObservationsCsv(h + "left,1,2,3,0,0,0,10,0,5,5\nright,1,2,3,0,0,0,10,0,5,5\nleft,1,2,3,0,0,0,10,0,50,5\n",
                                   "obs.csv");
  ASSERT_TRUE(parsed.ok());
  st = CheckPtuObservations(*parsed, PtuRange{}, "obs.csv");
  EXPECT_EQ(st.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(st.message().find("obs.csv:4: a second spot in the same left image as obs.csv:2"), std::string::npos)
      << st.message();
  // The same arm pose with other PTU readings is a different image.
  parsed = ParsePtuObservationsCsv(h + "left,1,2,3,0,0,0,10,0,5,5\nleft,1,2,3,0,0,0,11,0,50,5\n", "obs.csv");
  ASSERT_TRUE(parsed.ok());
  EXPECT_TRUE(CheckPtuObservations(*parsed, PtuRange{}, "obs.csv").ok());
  PtuRange inverted;
  inverted.tilt_min_rad = 1;
  EXPECT_FALSE(CheckPtuObservations(*parsed, inverted, "obs.csv").ok());
}

}  // namespace
}  // namespace idi::calib
