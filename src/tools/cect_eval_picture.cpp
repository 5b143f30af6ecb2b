#include "cect_eval_picture.h"

#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace massage_cell::tools::cect_eval {

void writePicture(const Options& o, const Condition& c, int subject, const cect::CectFrame& f,
                  const cect::LocatedAcupoints& result, const std::map<std::string, Eigen::Vector3d>& anatomical,
                  const camera::StereoModel& geometry,
                  const std::function<bool(const cv::Point2f&, Eigen::Vector3d*)>& truth) {
  const cect::BackLandmarks& lm = result.landmarks;
  cv::Mat img;
  if (!f.leftRectified().empty()) {
    img = f.leftRectified().clone();
  } else {
    img = cv::Mat(o.height, o.width, CV_8UC3, cv::Scalar::all(0));
  }
  if (!f.left().contour.empty()) {
    std::vector<cv::Point> contour;
    for (const auto& p : f.left().contour) contour.emplace_back(cvRound(p.x), cvRound(p.y));
    cv::polylines(img, contour, true, cv::Scalar(255, 0, 255), 1, cv::LINE_AA);
  }
  if (lm.valid && lm.midline.size() > 1) {
    std::vector<cv::Point> mid;
    for (const auto& p : lm.midline) {
      const cv::Point2f q = cect::toImage(lm, p);
      mid.emplace_back(cvRound(q.x), cvRound(q.y));
    }
    cv::polylines(img, mid, false, cv::Scalar(0, 255, 255), 1, cv::LINE_AA);
  }
  for (const auto& [name, p] : anatomical) {
    const Eigen::Vector3d q = geometry.project(p);
    cv::drawMarker(img, cv::Point(cvRound(q.x()), cvRound(q.y())), cv::Scalar(255, 255, 255), cv::MARKER_CROSS, 5, 1);
  }
  for (const cect::LocatedAcupoint& a : result.points) {
    if (!a.placed) continue;
    Eigen::Vector3d gt;
    double err = std::numeric_limits<double>::infinity();
    if (a.valid && truth(a.rectified, &gt)) err = 1000.0 * (a.point.position - gt).norm();
    const cv::Scalar colour = err < 5.0    ? cv::Scalar(0, 220, 0)
                              : err < 10.0 ? cv::Scalar(0, 165, 255)
                                           : cv::Scalar(0, 0, 255);
    cv::circle(img, cv::Point(cvRound(a.rectified.x), cvRound(a.rectified.y)), 2, colour, -1, cv::LINE_AA);
  }
  std::ostringstream text;
  text << c.name << ", subject " << subject;
  if (lm.valid && lm.body_angle_deg != 0.0)
    text << ", turned " << std::fixed << std::setprecision(1) << lm.body_angle_deg << " deg";
  if (!result.valid) text << ": " << result.reason;
  cv::putText(img, f.left().trunk.summary(), cv::Point(8, 36), cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(255, 255, 255),
              1, cv::LINE_AA);
  cv::putText(img, text.str(), cv::Point(8, 18), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(255, 255, 255), 1,
              cv::LINE_AA);
  std::ostringstream name;
  name << o.pictures << "/" << c.name << "_s" << std::setw(2) << std::setfill('0') << subject << ".png";
  if (!cv::imwrite(name.str(), img)) throw std::runtime_error("cannot write '" + name.str() + "'");
}

}  // namespace massage_cell::tools::cect_eval
