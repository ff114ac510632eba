// The sensor model: mean and variance of the output follow signal + black level and
// gain * signal + read^2 + 1/12 (shot noise, read noise, rounding), for every signal level.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "shared/sim/render/noise_rng.h"
#include "shared/sim/render/render.h"

namespace idi::sim {
namespace {

struct Stats {
  double mean = 0, var = 0;
};

Stats Measure(const cv::Mat& img8) {
  cv::Scalar mean, stddev;
  cv::meanStdDev(img8, mean, stddev);
  return {mean[0], stddev[0] * stddev[0]};
}

TEST(SensorTest, MeanAndVarianceFollowTheConfiguredModel) {
  SensorOptions s;
  s.gain_dn_per_electron = 0.12;
  s.read_noise_dn = 0.9;
  s.black_level_dn = 3;
  const int n = 256;
  for (const double level : {5.0, 20.0, 60.0, 120.0, 200.0}) {
    const cv::Mat irr(n, n, CV_32FC1, cv::Scalar(level));
    const Stats st = Measure(ApplySensor(irr, s, 42));
    const double expected_var = s.gain_dn_per_electron * level + s.read_noise_dn * s.read_noise_dn + 1.0 / 12;
    EXPECT_NEAR(st.mean, level + s.black_level_dn, 4 * std::sqrt(expected_var / (n * n)) + 0.01) << level;
    // The sample variance of 65536 values is good to about 0.6 %.
    EXPECT_NEAR(st.var / expected_var, 1.0, 0.03) << "level " << level << " var " << st.var;
  }
}

TEST(SensorTest, ReadNoiseHasTheNormalShapeIncludingItsTails) {
  // Read noise of 12 DN around 128 (no shot noise): the fractions beyond 1, 2, 3 and 3.5 sigma and
  // the fourth moment are those of a normal distribution. A generator with the right variance but the
  // wrong shape (a sum of uniforms, a table without tails, a wrong layer of a ziggurat) fails here.
  SensorOptions s;
  s.gain_dn_per_electron = 0;
  s.read_noise_dn = 12;
  const int n = 1024;
  const cv::Mat irr(n, n, CV_32FC1, cv::Scalar(128.0));
  const cv::Mat out = ApplySensor(irr, s, 99);
  const double sigma = std::sqrt(s.read_noise_dn * s.read_noise_dn + 1.0 / 12);
  std::vector<double> beyond(4, 0.0);
  const double limits[] = {1.0, 2.0, 3.0, 3.5};
  double m4 = 0;
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      const double z = (out.at<uint8_t>(r, c) - 128.0) / sigma;
      m4 += z * z * z * z;
      for (int k = 0; k < 4; ++k) beyond[static_cast<std::size_t>(k)] += std::abs(z) > limits[k] ? 1 : 0;
    }
  }
  const double count = static_cast<double>(n) * n;
  m4 /= count;
  // Two-sided normal tail fractions, computed for the 1 DN bins: |v - 128| > L sigma means
  // |v - 128| >= floor(L sigma) + 1 DN, i.e. beyond (floor(L sigma) + 0.5) DN before rounding.
  for (int k = 0; k < 4; ++k) {
    const double edge = (std::floor(limits[k] * sigma) + 0.5) / s.read_noise_dn;
    const double expected = std::erfc(edge / std::sqrt(2.0));
    const double measured = beyond[static_cast<std::size_t>(k)] / count;
    // Binomial standard error, 5 of them.
    EXPECT_NEAR(measured, expected, 5 * std::sqrt(expected * (1 - expected) / count))
        << "beyond " << limits[k] << " sigma";
  }
  EXPECT_NEAR(m4, 3.0, 0.05);  // its standard error is about 0.01
}

TEST(SensorTest, FewElectronsArePoissonDistributed) {
  // One DN per electron, no read noise: the output is a Poisson count (mean = variance), including
  // its integer values.
  SensorOptions s;
  s.gain_dn_per_electron = 1.0;
  s.read_noise_dn = 0;
  for (const double level : {0.5, 3.0, 12.0}) {
    const cv::Mat irr(256, 256, CV_32FC1, cv::Scalar(level));
    const cv::Mat out = ApplySensor(irr, s, 7);
    const Stats st = Measure(out);
    EXPECT_NEAR(st.mean, level, 0.03 * std::max(1.0, std::sqrt(level)));
    EXPECT_NEAR(st.var / level, 1.0, 0.04) << level;
    // P(0) = exp(-level).
    const double zeros = static_cast<double>(cv::countNonZero(out == 0)) / (256.0 * 256.0);
    EXPECT_NEAR(zeros, std::exp(-level), 0.01);
  }
}

TEST(SensorTest, NoiseFreeRoundsAndClips) {
  SensorOptions s;
  s.noise = false;
  s.black_level_dn = 2;
  cv::Mat irr(1, 5, CV_32FC1);
  irr.at<float>(0, 0) = -4;
  irr.at<float>(0, 1) = 10.49f;
  irr.at<float>(0, 2) = 10.51f;
  irr.at<float>(0, 3) = 252.4f;
  irr.at<float>(0, 4) = 900;
  const cv::Mat out = ApplySensor(irr, s, 0);
  EXPECT_EQ(out.at<uint8_t>(0, 0), 2);
  EXPECT_EQ(out.at<uint8_t>(0, 1), 12);
  EXPECT_EQ(out.at<uint8_t>(0, 2), 13);
  EXPECT_EQ(out.at<uint8_t>(0, 3), 254);
  EXPECT_EQ(out.at<uint8_t>(0, 4), 255);
}

TEST(SensorTest, SameSeedSameNoiseAndChannelsAreIndependent) {
  SensorOptions s;
  const cv::Mat irr(64, 64, CV_32FC3, cv::Scalar(50, 80, 120));
  const cv::Mat a = ApplySensor(irr, s, 5), b = ApplySensor(irr, s, 5), c = ApplySensor(irr, s, 6);
  ASSERT_EQ(a.type(), CV_8UC3);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_L1), 0);
  std::vector<cv::Mat> ch;
  cv::split(a, ch);
  cv::Mat d0, d1;
  ch[0].convertTo(d0, CV_64F);
  ch[1].convertTo(d1, CV_64F);
  d0 -= cv::mean(d0)[0];
  d1 -= cv::mean(d1)[0];
  const double corr = d0.dot(d1) / std::sqrt(d0.dot(d0) * d1.dot(d1));
  EXPECT_LT(std::abs(corr), 0.1);
}

// The sensor as it was first written, one pixel and one draw at a time from the generator: ApplySensor
// draws its words in blocks and takes runs of pixels at once, and must give every pixel the same words
// and so the same value (the noise an image gets for a seed is part of what the tests that use rendered
// images rely on).
cv::Mat SensorOnePixelAtATime(const cv::Mat& irr, const SensorOptions& s, uint64_t seed) {
  cv::Mat out(irr.rows, irr.cols, CV_MAKETYPE(CV_8U, irr.channels()));
  internal::Xoshiro256 rng(seed ^ 0x5EEDF00DULL);
  const bool shot = s.noise && s.gain_dn_per_electron > 0, read = s.noise && s.read_noise_dn > 0;
  const double gain = s.gain_dn_per_electron, read_var = read ? s.read_noise_dn * s.read_noise_dn : 0.0;
  for (int r = 0; r < irr.rows; ++r) {
    for (int k = 0; k < irr.cols * irr.channels(); ++k) {
      double v = std::max(0.0, static_cast<double>(irr.ptr<float>(r)[k]));
      if (shot && v > 30 * gain) {
        v += std::sqrt(gain * v + read_var) * internal::NormalFrom(rng);
      } else {
        if (shot) v = gain * internal::PoissonFrom(rng, v / gain);
        if (read) v += s.read_noise_dn * internal::NormalFrom(rng);
      }
      out.ptr<uint8_t>(r)[k] = static_cast<uint8_t>(std::nearbyint(std::clamp(v + s.black_level_dn, 0.0, 255.0)));
    }
  }
  return out;
}

TEST(SensorTest, BlockDrawsGiveEveryPixelTheWordsOfOneAtATime) {
  // Rows of 101 values (not a multiple of the runs) from below 0 to above 255, dark pixels (Poisson
  // draws, whose word count varies) scattered among bright ones, NaN, and read noise high enough that
  // many words fall outside their ziggurat rectangles and into the wedges and the tail.
  cv::Mat irr(37, 101, CV_32FC1);
  for (int r = 0; r < irr.rows; ++r) {
    for (int c = 0; c < irr.cols; ++c) {
      const int i = r * irr.cols + c;
      irr.at<float>(r, c) = i % 13 == 0 ? 1.5f : static_cast<float>(-20 + (i * 37) % 300);
    }
  }
  irr.at<float>(3, 7) = std::numeric_limits<float>::quiet_NaN();
  cv::Mat colour;
  cv::merge(std::vector<cv::Mat>{irr, irr * 0.5, irr + 10}, colour);
  std::vector<SensorOptions> variants(5);
  variants[1].read_noise_dn = 0;         // shot noise alone
  variants[2].gain_dn_per_electron = 0;  // read noise alone
  variants[3].read_noise_dn = 40;        // wide normals
  variants[3].black_level_dn = 4;
  variants[4].noise = false;  // rounding and clipping only
  int differing = 0, compared = 0;
  for (std::size_t v = 0; v < variants.size(); ++v) {
    for (const cv::Mat& image : {irr, colour}) {
      for (const uint64_t seed : {1ULL, 77ULL, 123456789ULL}) {
        const cv::Mat a = ApplySensor(image, variants[v], seed);
        const cv::Mat b = SensorOnePixelAtATime(image, variants[v], seed);
        ASSERT_EQ(a.type(), b.type());
        differing += cv::countNonZero(a.reshape(1) != b.reshape(1));
        compared += static_cast<int>(a.total()) * a.channels();
      }
    }
    EXPECT_EQ(differing, 0) << "variant " << v << ": " << differing << " of " << compared << " values differ";
  }
}

TEST(SensorTest, BadOptionsAreRejected) {
  SensorOptions s;
  s.read_noise_dn = -1;
  EXPECT_EQ(s.Check().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.Check().message().find("read_noise_dn"), std::string::npos);
  s = SensorOptions();
  s.gain_dn_per_electron = std::nan("");
  EXPECT_FALSE(s.Check().ok());
  RenderOptions r;
  r.psf_sigma_px = -0.5;
  EXPECT_NE(r.Check().message().find("psf_sigma_px"), std::string::npos);
  r = RenderOptions();
  r.sensor.read_noise_dn = -0.1;
  EXPECT_FALSE(r.Check().ok());
  // The refused value as it was given: a tiny negative one read "got -0.000000", a huge one 300 digits.
  r = RenderOptions();
  r.psf_sigma_px = -1e-9;
  EXPECT_NE(r.Check().message().find("got -1e-09"), std::string::npos) << r.Check().message();
  r.psf_sigma_px = 1e300;
  EXPECT_NE(r.Check().message().find("got 1e+300"), std::string::npos) << r.Check().message();
}

}  // namespace
}  // namespace idi::sim
