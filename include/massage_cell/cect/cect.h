// CECT: Correspondences from Epipolar geometry and Contours via Triangle
// barycentric coordinates (thesis Ch. 3; the extract holds only its abstract
// and captions, so the details below are our design). ROS-free.
//
// Per stereo pair (CectFrame::analyse):
//  1. rectify both views (camera::StereoModel), segment the back in each
//     (segmentation.h);
//  2. foundational correspondences: left contour samples; each one's
//     epipolar line (its rectified row) crosses the right view's back border
//     at sub-pixel positions (score zero crossings); of several crossings the
//     one on the same side of the back (entering / leaving along the row) in
//     the same order along the row is taken;
//  3. interior: Delaunay triangulation of the foundational left points; a
//     point's barycentric coordinates in its triangle and in the triangles
//     next to it give candidate right positions; three geometric constraints
//     decide (see CectParams and cect.cpp); interior seeds on a grid are
//     refined along their epipolar line by normalised cross-correlation
//     around the barycentric prediction and, once they pass the constraints,
//     join the triangulation (so the transfer follows the back's curvature);
//  4. triangulation to 3D in the left camera's optical frame with a
//     covariance from the candidates' spread and the matching precision.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "massage_cell/camera/stereo_model.h"
#include "massage_cell/cect/depth_gate.h"
#include "massage_cell/cect/segmentation.h"
#include "massage_cell/cect/skin_markers.h"

namespace massage_cell::cect {

/// The view of the back the pixel parameters below are given for: 640x480,
/// fx 500 px, baseline 0.1 m, the back's contour ~0.91 m from the camera
/// (the subject prone on a table 0.95 m below it; the contour's median
/// disparity is 53-57 px over the simulator's 28 subjects). The contour's
/// median disparity d measures a view's own scale: fx / Z = d / B pixels per
/// metre on the back.
constexpr double kReferencePixelsPerMetre = 550.0;  ///< fx / Z of the reference contour

struct CectParams {
  SegmentationParams segmentation;
  /// The floor and room far behind the table are not the back, whatever
  /// their colour (depth_gate.h); gap 0: colour alone decides.
  DepthGateParams background;
  /// Coloured skin markers on the back (a kit: skin_markers.h); unset: none. Their dots count as skin in the
  /// segmentation, and locateAcupoints takes C7 / L4 from those found in both views.
  std::optional<SkinMarkerOptions> skin_markers;
  /// Scale the pixel parameters to the view (see scaledParams): with a
  /// camera of another resolution or focal length, or farther from the
  /// back, the parameters below still mean the same on the skin. false:
  /// they are used as given (in the view's own pixels).
  bool auto_scale = true;
  /// The depths the back may lie at, metres from the left camera along its
  /// axis: the disparity search follows from them and the calibration
  /// (disparityRange), so a new rig needs no change. The default suits a
  /// camera above a massage table.
  double min_depth = 0.25;
  double max_depth = 2.5;
  /// Explicit disparity bounds, rectified pixels (0: from max_depth /
  /// min_depth). Crossings outside [min, max] are not correspondences.
  double min_disparity = 0.0;
  double max_disparity = 0.0;
  double sample_spacing = 4.0;  ///< rows between foundational samples, pixels
  /// A border crossing whose border runs within this angle of the epipolar
  /// line (degrees) is ill-conditioned (its position along the row is
  /// uncertain) and not used.
  double min_crossing_angle = 20.0;
  /// Contour parts within min_crossing_angle of the epipolar lines (the
  /// neck base) are matched by aligning the edge's shape y(x) between the
  /// views over +-edge_window px (0: not matched; they stay without
  /// foundational correspondences).
  double edge_window = 32.0;
  /// An edge sample is matched only where shifting the alignment 2 px either
  /// way raises the mean squared misalignment by this much (px^2): a
  /// straight edge along the rows cannot fix its shift.
  double edge_min_bend = 0.25;
  /// The final triangulation drops triangles with an edge longer than this
  /// many seed steps (0: keep all): they bridge gaps in the correspondences,
  /// and the pixels under them are extrapolated from the seeds instead.
  double max_triangle_edge = 2.0;
  int seed_step = 16;  ///< interior seeds every N pixels (0: contour only, the plain thesis method)
  /// ... and, in the final (seed_step) pass, every N columns (0: seed_step).
  /// Across the body the back has its finest relief: the spine's groove
  /// between the paraspinal ridges, ~40 px ridge to ridge at 640x480. With
  /// seed_step columns its reconstruction depends on where the columns fall
  /// (the body's place in the image); half-step columns make it independent
  /// of that. Along the body the back
  /// changes slowly.
  int seed_column_step = 8;
  int ncc_radius = 11;  ///< matching window half-width r for the refinement along the epipolar line
  /// Window half-height (0: = ncc_radius). Taller than wide suits the back:
  /// its few structures (spine groove, paraspinal ridges, scapulae) run
  /// along the body, across the epipolar lines, and depth changes slowly
  /// along them.
  int ncc_half_height = 0;
  /// Band-pass of the matching images: difference of Gaussians with these
  /// sigmas, pixels (bandpass_high <= 0: plain grey).
  double bandpass_low = 1.5;
  double bandpass_high = 6.0;
  /// Sheen removal (dichromatic model, see cect.cpp): the specular part,
  /// estimated per pixel from the colour, smoothed by a Gaussian of this
  /// sigma (pixels), is taken off before matching (0: off).
  double sheen_sigma = 6.0;
  /// Smooth the specular part by "twicing" (Tukey): the Gaussian's
  /// residual smoothed once more and added back, 2 G*S - G*G*S. A single
  /// Gaussian flattens the sheen's peaks on the ridges (a residual that moves
  /// with the viewpoint and biases the matches); twicing keeps them at
  /// nearly the same noise.
  bool sheen_twicing = true;
  /// Seeds sit at least this many pixels inside the back's border (< 0:
  /// ncc_radius + 2, every window inside the back).
  double seed_margin = -1.0;
  double seed_search = 10.0;  ///< pixels searched either side of a seed's barycentric prediction
  /// How far the back may rise above its contour, metres: the first seeds,
  /// predicted from the contour alone, are searched that far nearer.
  double max_relief = 0.3;
  /// Seeds are smoothed by a local quadratic over this many seed steps (0: off).
  double smooth_radius = 6.0;
  /// The smoothing fit also has x^3 and x^4 terms: across the body (which
  /// lies along the image columns, head up or down, as in the acupoint
  /// model) the back is a dome with two paraspinal ridges and the spine's
  /// groove between them, ~0.5 px deep and ~40 px ridge to ridge at
  /// 640x480, more than a quadratic over the (wide, noise-averaging)
  /// smoothing radius can follow.
  bool quartic_across = true;
  /// Before smoothing, seeds are matched again with a window slanted by the
  /// local disparity gradient g of their neighbours' quadratic (needs
  /// smooth_radius > 0): on the shoulders' slopes and the flanks a
  /// fronto-parallel window's peak is biased by up to ~1 px.
  bool slanted_windows = true;
  /// ... only where the slant moves the window's edges by at least this
  /// much, |g.x| r + |g.y| ry (pixels; scales with the image size), and
  /// within 2 seed steps of a border along the rows (the shoulders' top,
  /// where the one-sided quadratic underestimates the slope).
  double min_slant = 1.5;
  /// Fill the band between the contour and the first seeds from a rim
  /// profile (disparity ~ sqrt of the distance to the occluding contour,
  /// fitted to the seeds nearby) instead of interpolating linearly. The
  /// profile's values stay within the range of the rim's and those seeds'
  /// disparities (+- continuity_margin): beyond it the fit extrapolates.
  /// Seeds that keep the fit from holding are dropped, worst first, while
  /// five remain: on a steep flank (beside an arm's crease the trunk falls
  /// ~10 px of disparity within 20 px of its border) a window's peak can be
  /// several pixels off, and the linear interpolation from it worse still.
  bool rim_profile = true;
  double query_search = 0.0;  ///< pixels searched either side of a query's prediction (0: transfer only, the default:
                              ///< single windows on skin are noisier than the smoothed seeds, and the reported sigma
                              ///< undercovers them)
  /// Weakest accepted correlation peak. Low on purpose: on dark skin and
  /// under sheen the skin's texture correlates weakly, and a gap without
  /// seeds is extrapolated far worse (up to 30 mm) than weak seeds err;
  /// constraints 2 and 3 reject the wrong ones.
  double min_ncc = 0.4;
  /// Constraint 1 (candidate agreement): the candidates from the triangle
  /// and its neighbours must agree within this many pixels.
  double max_candidate_spread = 4.0;
  /// Constraint 2 (continuity / order): a refined disparity may leave the
  /// range of its triangle's vertices by at most this many pixels.
  double continuity_margin = 3.0;
  /// Constraint 3 (left-right consistency): matching back from the right
  /// view must land within this many pixels of the left point.
  double lr_tolerance = 1.0;
  /// Back pixels outside the triangulation (next to a contour running along
  /// the epipolar lines, e.g. the neck base) are extrapolated from the seeds'
  /// local quadratic when the nearest seed is within this many seed steps
  /// and the seeds fit it within 3 pixel_sigma rms (0: never; they stay
  /// valid = false).
  double max_extrapolation = 1.5;
  /// Such pixels in the border band where no seed window fits (closer to
  /// the border than the seeds' margin; there the surface rolls off, which
  /// the seeds' quadratic cannot see) are matched directly instead when
  /// their own window fixes the disparity: a window restricted to the back
  /// in both views (3 px in from the border), searched within
  /// continuity_margin of the extrapolation, kept when the correlation
  /// peak's sharpness (minus its second difference, per px^2: how much
  /// texture the window holds, e.g. the vertebra prominens at the neck
  /// base) reaches this and constraint 3 holds (0: never). Band pixels
  /// inside the triangulation next to a border along the rows (the
  /// shoulders' top, where the first seeds' windows reach across a steep
  /// ledge) take the mean of the transfer and such a match, with a window
  /// wide along the border and short across it (same gate).
  double direct_min_sharpness = 0.03;
  /// Pixels: localisation noise of a matched point (covariance; with
  /// auto_scale reported times the view's scale, the gates below use it as given).
  double pixel_sigma = 0.3;
  /// The disparity's uncertainty also has two structural parts, added in
  /// quadrature to the matching noise (pixel_sigma, the candidates' spread,
  /// the extrapolation's):
  /// - next to the back's border, border_sigma pixels at the border falling
  ///   linearly to 0 at border_sigma_reach seed steps inside it. That band is
  ///   filled from the rim profile and the first seeds, whose windows reach
  ///   across the steepest relief: it errs ~1 px rms where the interior errs
  ///   0.3 (cect_eval --by-border measures both and the calibration);
  /// - slope_sigma times the magnitude of the local disparity gradient
  ///   (pixels per pixel; the containing triangle's plane, or the seeds'
  ///   quadratic outside the triangulation): a window on sloping skin
  ///   compares pixels of different disparities.
  /// Calibrated on the simulator's subjects by maximum likelihood (every 4th
  /// back pixel; docs/cect.md, design notes).
  /// 0 turns a part off.
  double border_sigma = 1.0;
  double border_sigma_reach = 3.0;  ///< seed steps
  double slope_sigma = 2.0;
};

/// The view's scale against the reference view: (median disparity of its
/// contour / baseline) / kReferencePixelsPerMetre, in steps of 2^(1/4)
/// (19 %), so that the reference rig uses the parameters as given whatever
/// the body (d 51-59 px at B 0.1 m). 1 for a non-positive disparity or baseline.
double viewScale(double median_disparity, double baseline);

/// Every problem of `params` that CECT cannot work with (empty when none): depths and disparities out of order,
/// non-positive steps, windows and uncertainties, NaN; each names the parameter (the cect node's and --param's name).
/// The one check the node's parameters and the tools' go through.
std::vector<std::string> checkParams(const CectParams& params);

/// The disparities searched, [min, max] rectified pixels: min_disparity /
/// max_disparity where given (> 0), else those of max_depth / min_depth for
/// this calibration (at least 0.5 px, at most the image width - 1). An empty
/// range ([0, 0]) for non-finite values.
cv::Vec2d disparityRange(const CectParams& p, const camera::StereoModel& geometry);

/// `p` with its pixel parameters scaled by `scale`: sizes on the image
/// (window, seed grid, band-pass and sheen sigmas, contour sampling, edge
/// window, seed margin, the segmentation's blur, morphology and contour
/// spacing; a window's extent 2r + 1 scales as a whole) and the disparity
/// tolerances (seed_search, query_search, max_candidate_spread,
/// continuity_margin, min_slant, border_sigma, slope_sigma); direct_min_sharpness (per px^2) by
/// 1 / scale^2. Scale-free (seed steps, metres, angles, NCC) and sub-pixel
/// ones (lr_tolerance, pixel_sigma; the reported uncertainty scales the
/// latter itself, CectFrame::matchingSigma) stay, and so do min_disparity and
/// max_disparity.
CectParams scaledParams(const CectParams& p, double scale);

/// One correspondence in rectified coordinates (same row in both views).
struct Correspondence {
  cv::Point2f left;
  float disparity = 0.0f;  ///< left.x - right.x
  float sigma = 0.0f;      ///< standard deviation of the disparity, pixels
  enum class Source {
    kContour,     ///< foundational: a contour sample and its epipolar line's crossing
    kSeed,        ///< interior seed matched along its epipolar line (smoothed)
    kRimProfile,  ///< between the contour and the first seeds, from the rim profile
    kEdge,        ///< foundational: a contour sample on an edge along the rows, matched by the edge's shape
  };
  Source source = Source::kContour;
  bool foundational() const { return source == Source::kContour || source == Source::kEdge; }
};

struct LocalizedPoint {
  bool valid = false;
  std::string reason;                                    ///< why not valid
  cv::Point2f pixel;                                     ///< the query, raw left image
  cv::Point2f rectified;                                 ///< the query, rectified left image
  double disparity = 0.0;                                ///< rectified pixels
  double disparity_sigma = 0.0;                          ///< pixels
  Eigen::Vector3d position = Eigen::Vector3d::Zero();    ///< left optical frame, metres
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  ///< metres^2
  double spread = 0.0;                                   ///< spread of the candidates, pixels (constraint 1)
  int candidates = 0;
  /// Outside the triangulation, from the seeds' local quadratic (see
  /// CectParams::max_extrapolation); its uncertainty grows with the distance.
  bool extrapolated = false;
};

struct CectTimings {
  /// segment_ms: both views segmented and their matching images made (in parallel).
  double rectify_ms = 0, segment_ms = 0, foundational_ms = 0, interior_ms = 0, total_ms = 0;
};

/// What became of the interior seeds (both passes).
struct SeedStats {
  int tried = 0;         ///< grid points matched
  int no_peak = 0;       ///< no texture, or the correlation peak at the end of the search range
  int weak = 0;          ///< peak below min_ncc
  int left_right = 0;    ///< failed constraint 3
  int continuity = 0;    ///< failed constraint 2 against their grid neighbours
  int smoothing = 0;     ///< dropped: too far from their local quadratic
  int rim_outliers = 0;  ///< dropped: off the rim profile of the border beside them (rim_profile)
  int accepted = 0;      ///< joined the triangulation (before smoothing)
};

/// The analysis of one stereo pair; answers point queries afterwards.
class CectFrame {
 public:
  CectFrame() = default;
  /// Analyses a pair (BGR CV_8UC3, raw or rectified as `geometry` says).
  /// Throws std::invalid_argument for images that do not match the geometry
  /// (size, type, empty); problems of content leave valid() false with a reason.
  static CectFrame analyse(const cv::Mat& left, const cv::Mat& right, const camera::StereoModel& geometry,
                           const CectParams& params);

  bool valid() const { return valid_; }
  const std::string& reason() const { return reason_; }
  const Segmentation& left() const { return left_seg_; }    ///< rectified left view
  const Segmentation& right() const { return right_seg_; }  ///< rectified right view
  /// The rectified views, the frame's own (never the caller's buffers): they live as long as the frame.
  const cv::Mat& leftRectified() const { return left_rect_; }
  const cv::Mat& rightRectified() const { return right_rect_; }
  const std::vector<Correspondence>& vertices() const { return vertices_; }
  std::size_t foundationalCount() const;
  /// Delaunay triangles over vertices() (indices).
  const std::vector<cv::Vec3i>& triangles() const { return triangles_; }
  const CectTimings& timings() const { return timings_; }
  const SeedStats& seedStats() const { return seed_stats_; }
  const camera::StereoModel& geometry() const { return geometry_; }
  /// The parameters used: with auto_scale, scaled to the view (scale()).
  const CectParams& params() const { return params_; }
  /// The view's scale against the reference (viewScale; 1 without
  /// auto_scale, and before the contour is matched).
  double scale() const { return scale_; }
  /// The disparities searched (disparityRange).
  cv::Vec2d disparityRange() const { return disparity_range_; }
  /// What the segmentation was told is far background (depth_gate.h).
  const DepthGate& background() const { return background_; }

  /// A raw left-image pixel -> its 3D point (valid = false with a reason
  /// outside the back, outside the triangulation, or when the constraints
  /// reject it).
  LocalizedPoint localize(const cv::Point2f& left_raw_pixel) const;
  /// Same, for a rectified left pixel.
  LocalizedPoint localizeRectified(const cv::Point2f& left_rect_pixel) const;

  /// Debug picture: the rectified left view with the contour, triangles and vertices.
  cv::Mat drawDebug() const;

 private:
  bool valid_ = false;
  std::string reason_;
  camera::StereoModel geometry_;
  CectParams params_;
  double scale_ = 1.0;
  cv::Vec2d disparity_range_{0.0, 0.0};
  DepthGate background_;
  Segmentation left_seg_, right_seg_;
  cv::Mat left_rect_, right_rect_;    ///< BGR
  cv::Mat left_marks_, right_marks_;  ///< CV_8U: the skin markers' dots (skinMarkerPixels; empty without a kit)
  cv::Mat left_grey_, right_grey_;    ///< CV_32F
  cv::Mat left_inner_, right_inner_;  ///< the masks 3 px in from the border (direct matches)
  cv::Mat seed_region_;               ///< left pixels at least seed_margin inside the border
  int seed_margin_ = 0;               ///< that margin, pixels
  cv::Mat border_distance_;           ///< CV_32F, rectified left: distance to the back's border, pixels
  std::vector<Correspondence> vertices_;
  std::vector<cv::Vec3i> triangles_;
  std::vector<std::vector<int>> vertex_triangles_;  ///< triangles around each vertex
  cv::Mat triangle_index_;                          ///< CV_32S, rectified left: containing triangle, -1 outside
  CectTimings timings_;
  SeedStats seed_stats_;

  /// Barycentric transfer of a rectified left pixel: the median disparity of
  /// the candidates from its triangle and the triangles sharing an edge with
  /// it; NaN outside the triangulation. `spread` = max - min candidate.
  /// `gradient` (optional): the containing triangle's disparity plane's
  /// gradient (dd/dx, dd/dy).
  double transfer(const cv::Point2f& q, double* spread, int* count, cv::Point2d* gradient = nullptr) const;
  /// `sigma` (the matching's) with the structural parts added (see
  /// CectParams::border_sigma) for rectified left pixel q; without the
  /// border's part for a pixel's own direct match (not `interpolated`).
  double structuralSigma(const cv::Point2f& q, double sigma, const cv::Point2d& gradient,
                         bool interpolated = true) const;
  /// pixel_sigma in the reported uncertainty: times the view's scale (a
  /// matched point's error in pixels grows with the pixels per metre:
  /// cect_eval at twice and half the reference view, ~1.8x and ~0.7x inside
  /// the back); pixel_sigma's gates use it as given.
  double matchingSigma() const { return params_.pixel_sigma * scale_; }
  /// The direct match of a border-band pixel (see direct_min_sharpness): a
  /// (2 rx + 1) x (2 ry + 1) window restricted to the back in both views,
  /// searched within continuity_margin of `d`; false without a sharp peak or
  /// when constraint 3 fails.
  bool directMatch(const cv::Point2f& q, double d, int rx, int ry, double* disparity) const;
  /// Rectified left pixel in the border band (outside seed_region_) next to a
  /// border that runs along the rows: the back ends within the seed margin
  /// above or below it, and not left or right of it.
  bool inRowBorderBand(int x, int y) const;
  /// The fallback of localizeRectified outside the triangulation.
  LocalizedPoint extrapolate(const cv::Point2f& q, LocalizedPoint out) const;
  /// `out` completed with the 3D point of rectified pixel q at disparity d and its covariance.
  LocalizedPoint triangulated(const cv::Point2f& q, double d, double sigma, LocalizedPoint out) const;

  friend class CectFrameBuilder;
};

}  // namespace massage_cell::cect
