#include "opencv_threads.hpp"

#include <opencv2/core/utility.hpp>

namespace st::detail {

void useOpenCvSequentially() {
  static const bool done = [] {
    cv::setNumThreads(0);
    return true;
  }();
  (void)done;
}

}  // namespace st::detail
