// Checks a browser screenshot of the report is not blank: the expected size, and a page with
// content (many non-white pixels, real contrast). usage: check_screenshot PNG MIN_WIDTH MIN_HEIGHT
#include <cstdio>
#include <cstdlib>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: check_screenshot PNG MIN_WIDTH MIN_HEIGHT\n");
    return 2;
  }
  const cv::Mat img = cv::imread(argv[1], cv::IMREAD_COLOR);
  if (img.empty()) {
    std::fprintf(stderr, "%s: cannot read the screenshot\n", argv[1]);
    return 1;
  }
  cv::Mat grey;
  cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
  cv::Scalar mean, sd;
  cv::meanStdDev(grey, mean, sd);
  const double non_white = static_cast<double>(cv::countNonZero(grey < 245)) / static_cast<double>(grey.total());
  std::printf("%s: %dx%d, grey mean %.1f, sd %.1f, %.1f%% non-white\n", argv[1], img.cols, img.rows, mean[0], sd[0], 100 * non_white);
  if (img.cols < std::atoi(argv[2]) || img.rows < std::atoi(argv[3])) {
    std::fprintf(stderr, "screenshot smaller than %sx%s\n", argv[2], argv[3]);
    return 1;
  }
  if (sd[0] < 20 || non_white < 0.10) {
    std::fprintf(stderr, "the screenshot is (nearly) blank\n");
    return 1;
  }
  return 0;
}
