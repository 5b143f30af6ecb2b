// ChArUco board: drawing, detection in a rectified pair (OpenCV aruco),
// corner triangulation and the board fit that gives the reference point.
#include "massage_cell/calib/stereo_marker.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

#include <Eigen/SVD>

#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include "massage_cell/camera/point_spread.h"

namespace massage_cell::calib {
namespace {

cv::Ptr<cv::aruco::CharucoBoard> makeBoard(const CharucoSpec& spec) {
  spec.validate();
  const cv::Ptr<cv::aruco::Dictionary> dictionary = cv::aruco::getPredefinedDictionary(spec.dictionary);
  return cv::aruco::CharucoBoard::create(spec.squares_x, spec.squares_y, static_cast<float>(spec.square_length),
                                         static_cast<float>(spec.marker_length), dictionary);
}

cv::Mat toGrey(const cv::Mat& image, const char* which) {
  if (image.empty()) throw std::invalid_argument(std::string("detectMarker: the ") + which + " image is empty");
  if (image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3)) {
    throw std::invalid_argument(std::string("detectMarker: the ") + which + " image must be 8-bit grey or BGR");
  }
  if (image.channels() == 1) return image;
  cv::Mat grey;
  cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  return grey;
}

/// Refines chessboard corners to ~0.01 px. interpolateCornersCharuco stops
/// cornerSubPix at 0.1 px (aruco's default accuracy); this runs it again to
/// 0.001 px with the largest window that keeps the markers' own corners out:
/// half-size = the white margin between square and marker, in pixels, less one.
void refineCorners(const cv::Mat& grey, const std::vector<std::vector<cv::Point2f>>& markers,
                   const cv::aruco::CharucoBoard& board, std::vector<cv::Point2f>* corners) {
  if (corners->empty()) return;
  std::vector<double> sides;  // marker side lengths, pixels
  for (const auto& m : markers) {
    for (int k = 0; k < 4; ++k) sides.push_back(cv::norm(m[k] - m[(k + 1) % 4]));
  }
  std::nth_element(sides.begin(), sides.begin() + sides.size() / 2, sides.end());
  const double px_per_m = sides[sides.size() / 2] / board.getMarkerLength();
  const double margin_px = 0.5 * (board.getSquareLength() - board.getMarkerLength()) * px_per_m;
  const int half = std::clamp(static_cast<int>(std::floor(margin_px)) - 1, 2, 10);
  cv::cornerSubPix(grey, *corners, cv::Size(half, half), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::MAX_ITER | cv::TermCriteria::EPS, 100, 1e-3));
}

/// ChArUco corners of one view, id -> rectified pixel; empty when no marker is seen.
std::map<int, cv::Point2f> charucoCorners(const cv::Mat& grey, const cv::Ptr<cv::aruco::CharucoBoard>& board) {
  std::vector<std::vector<cv::Point2f>> marker_corners, rejected;
  std::vector<int> marker_ids;
  const cv::Ptr<cv::aruco::DetectorParameters> params = cv::aruco::DetectorParameters::create();
  cv::aruco::detectMarkers(grey, board->dictionary, marker_corners, marker_ids, params, rejected);
  std::map<int, cv::Point2f> out;
  if (marker_ids.empty()) return out;
  cv::aruco::refineDetectedMarkers(grey, board, marker_corners, marker_ids, rejected);
  std::vector<cv::Point2f> corners;
  std::vector<int> ids;
  cv::aruco::interpolateCornersCharuco(marker_corners, marker_ids, grey, board, corners, ids);
  refineCorners(grey, marker_corners, *board, &corners);
  for (std::size_t i = 0; i < ids.size(); ++i) out[ids[i]] = corners[i];
  return out;
}

/// Corners seen in both views on (nearly) the same row.
void matchViews(const std::map<int, cv::Point2f>& left, const std::map<int, cv::Point2f>& right, double max_row_error,
                MarkerDetection* d) {
  for (const auto& [id, pl] : left) {
    const auto it = right.find(id);
    if (it == right.end() || std::abs(it->second.y - pl.y) > max_row_error) continue;
    d->ids.push_back(id);
    d->left_px.push_back(pl);
    d->right_px.push_back(it->second);
  }
  d->corners = static_cast<int>(d->ids.size());
}

/// Triangulated corners (3xN, rectified left frame, metres).
Eigen::Matrix3Xd triangulate(const MarkerDetection& d, const RectifiedGeometry& g) {
  const int n = d.corners;
  cv::Mat pl(2, n, CV_64F), pr(2, n, CV_64F);
  for (int i = 0; i < n; ++i) {
    pl.at<double>(0, i) = d.left_px[i].x;
    pl.at<double>(1, i) = d.left_px[i].y;
    pr.at<double>(0, i) = d.right_px[i].x;
    pr.at<double>(1, i) = d.right_px[i].y;
  }
  cv::Mat X;
  cv::triangulatePoints(cv::Mat(g.P_left), cv::Mat(g.P_right), pl, pr, X);
  X.convertTo(X, CV_64F);
  Eigen::Matrix3Xd out(3, n);
  for (int i = 0; i < n; ++i) {
    const double w = X.at<double>(3, i);
    out.col(i) = Eigen::Vector3d(X.at<double>(0, i), X.at<double>(1, i), X.at<double>(2, i)) / w;
  }
  return out;
}

}  // namespace

void CharucoSpec::validate() const {
  if (squares_x < 2 || squares_y < 2 || squares_x * squares_y < 6) {
    throw std::invalid_argument("CharucoSpec: need at least 2 x 2 squares and 6 in all, got " +
                                std::to_string(squares_x) + " x " + std::to_string(squares_y));
  }
  if (!(square_length > 0.0) || !std::isfinite(square_length)) {
    throw std::invalid_argument("CharucoSpec: square_length must be finite and > 0");
  }
  if (!(marker_length > 0.0 && marker_length < square_length)) {
    throw std::invalid_argument("CharucoSpec: marker_length must be > 0 and < square_length");
  }
  if (dictionary < 0 || dictionary > cv::aruco::DICT_ARUCO_ORIGINAL) {
    throw std::invalid_argument("CharucoSpec: dictionary must be a cv::aruco::PREDEFINED_DICTIONARY_NAME (0.." +
                                std::to_string(static_cast<int>(cv::aruco::DICT_ARUCO_ORIGINAL)) + ")");
  }
  const int markers = squares_x * squares_y / 2;
  const int available = cv::aruco::getPredefinedDictionary(dictionary)->bytesList.rows;
  if (markers > available) {
    throw std::invalid_argument("CharucoSpec: the board needs " + std::to_string(markers) +
                                " markers, the dictionary holds " + std::to_string(available));
  }
}

Eigen::Vector3d referencePointInBoard(const CharucoSpec& spec) {
  return Eigen::Vector3d(0.5 * spec.width(), 0.5 * spec.height(), 0.0);
}

cv::Mat drawBoard(const CharucoSpec& spec, double pixels_per_metre) {
  if (!(pixels_per_metre > 0.0) || !std::isfinite(pixels_per_metre)) {
    throw std::invalid_argument("drawBoard: pixels_per_metre must be finite and > 0");
  }
  const cv::Ptr<cv::aruco::CharucoBoard> board = makeBoard(spec);
  const cv::Size size(static_cast<int>(std::lround(spec.width() * pixels_per_metre)),
                      static_cast<int>(std::lround(spec.height() * pixels_per_metre)));
  cv::Mat image;
  board->draw(size, image, 0, 1);
  return image;
}

bool isRectified(const camera::CameraCalibration& c) {
  const bool no_distortion = std::all_of(c.D.begin(), c.D.end(), [](double v) { return v == 0.0; });
  const std::array<double, 9> identity{1, 0, 0, 0, 1, 0, 0, 0, 1};
  return no_distortion && c.R == identity;
}

RectifiedGeometry rectifiedGeometry(const camera::CameraCalibration& left, const camera::CameraCalibration& right) {
  const std::vector<std::string> problems = camera::checkStereoCalibration(left, right);
  if (!problems.empty()) {
    std::string message = "stereo calibration unusable:";
    for (const auto& p : problems) message += " " + p + ";";
    throw std::invalid_argument(message);
  }
  RectifiedGeometry g;
  g.P_left = cv::Matx34d(left.P.data());
  g.P_right = cv::Matx34d(right.P.data());
  const Eigen::Matrix3d R = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(left.R.data());
  g.left_from_rectified = R.transpose();
  return g;
}

cv::Mat rectify(const camera::CameraCalibration& calib, const cv::Mat& raw) {
  if (raw.cols != calib.width || raw.rows != calib.height) {
    throw std::invalid_argument("rectify: image is " + std::to_string(raw.cols) + "x" + std::to_string(raw.rows) +
                                ", its calibration " + std::to_string(calib.width) + "x" +
                                std::to_string(calib.height));
  }
  if (isRectified(calib)) return raw;
  const cv::Matx33d K(calib.K.data()), R(calib.R.data());
  const cv::Matx34d P(calib.P.data());
  const cv::Matx33d Pk = P.get_minor<3, 3>(0, 0);
  cv::Mat map1, map2, out;
  cv::initUndistortRectifyMap(K, calib.D, R, Pk, raw.size(), CV_32FC1, map1, map2);
  cv::remap(raw, out, map1, map2, cv::INTER_LINEAR);
  return out;
}

MarkerDetection detectMarker(const cv::Mat& left, const cv::Mat& right, const RectifiedGeometry& geometry,
                             const CharucoSpec& spec, const DetectOptions& options) {
  const cv::Mat gl = toGrey(left, "left");
  const cv::Mat gr = toGrey(right, "right");
  if (gl.size() != gr.size()) throw std::invalid_argument("detectMarker: the two images differ in size");
  if (options.min_corners < 4) throw std::invalid_argument("detectMarker: min_corners must be >= 4");
  const cv::Ptr<cv::aruco::CharucoBoard> board = makeBoard(spec);

  MarkerDetection d;
  const std::map<int, cv::Point2f> cl = charucoCorners(gl, board);
  const std::map<int, cv::Point2f> cr = charucoCorners(gr, board);
  matchViews(cl, cr, options.max_row_error, &d);
  if (d.corners < options.min_corners) {
    d.problem = "board corners: " + std::to_string(cl.size()) + " left, " + std::to_string(cr.size()) + " right, " +
                std::to_string(d.corners) + " in both on one row (need " + std::to_string(options.min_corners) + ")";
    return d;
  }
  const Eigen::Matrix3Xd in_camera = geometry.left_from_rectified * triangulate(d, geometry);
  Eigen::Matrix3Xd in_board(3, d.corners);
  for (int i = 0; i < d.corners; ++i) {
    const cv::Point3f& p = board->chessboardCorners[static_cast<std::size_t>(d.ids[i])];
    in_board.col(i) = Eigen::Vector3d(p.x, p.y, p.z);
  }
  // Corners along one line leave the board's turn about that line free.
  const Eigen::Matrix3Xd centred = in_board.colwise() - in_board.rowwise().mean();
  const Eigen::Vector3d spread = camera::principalAxes(centred).spread;
  if (spread(1) < 0.5 * spec.square_length) {
    d.problem = "the " + std::to_string(d.corners) + " board corners seen in both views lie on one line";
    return d;
  }
  d.camera_from_board.matrix() = Eigen::umeyama(in_board, in_camera, false);
  const Eigen::Matrix3Xd fitted = d.camera_from_board * in_board;
  d.fit_rms_mm = std::sqrt((fitted - in_camera).colwise().squaredNorm().mean()) * 1e3;
  if (!(d.fit_rms_mm <= options.max_fit_rms_mm)) {
    d.problem = "board fit RMS " + std::to_string(d.fit_rms_mm) + " mm over " + std::to_string(d.corners) +
                " corners exceeds " + std::to_string(options.max_fit_rms_mm) + " mm";
    return d;
  }
  d.point = d.camera_from_board * referencePointInBoard(spec);
  d.found = true;
  return d;
}

}  // namespace massage_cell::calib
