// CECT step 2: the foundational correspondences on the back's contour (row crossings, edges along the rows)
// and the triangulation over them (see cect.h, cect_detail.h).
#include "cect_detail.h"

namespace massage_cell::cect {

namespace {

/// Row (sub-pixel) of the back's border in each column of a view, along
/// an edge that runs across the columns: tracked column by column from
/// (x0, y0) in direction `dir` (+-1) over `count` columns, each time the
/// score's zero crossing nearest the last row (within 3 px; 6 px at the
/// start) whose sign change matches the edge's side (`down_into_back`:
/// the back lies below the edge). NaN where the edge turns too steep.
void trackEdge(const std::vector<std::vector<double>>& ys, const std::vector<std::vector<bool>>& rising, int x0,
               double y0, int dir, int count, bool down_into_back, std::vector<double>* out, int out_x0) {
  double last = y0;
  for (int k = 0; k < count; ++k) {
    const int x = x0 + dir * k;
    if (x < 0 || x >= static_cast<int>(ys.size())) break;
    const double reach = k == 0 ? 6.0 : 3.0;
    double best = std::numeric_limits<double>::quiet_NaN(), best_dist = reach;
    for (std::size_t j = 0; j < ys[static_cast<std::size_t>(x)].size(); ++j) {
      if (rising[static_cast<std::size_t>(x)][j] != down_into_back) continue;
      const double dist = std::abs(ys[static_cast<std::size_t>(x)][j] - last);
      if (dist <= best_dist) {
        best_dist = dist;
        best = ys[static_cast<std::size_t>(x)][j];
      }
    }
    if (!std::isfinite(best)) break;
    (*out)[static_cast<std::size_t>(x - out_x0)] = best;
    last = best;
  }
}

}  // namespace

/// Step 2: contour samples -> row crossings in the right view.
void CectFrameBuilder::foundational() {
  const CectParams& p = f_.params_;
  const auto& contour = f_.left_seg_.contour;
  const int n = static_cast<int>(contour.size());
  const double min_sin = std::sin(p.min_crossing_angle * M_PI / 180.0);
  struct Sample {
    cv::Point2f left;
    std::vector<double> cands;  ///< candidate disparities
    int unique = -1;            ///< index into cands chosen by the order rule, -1 none
    cv::Point2f normal;         ///< the contour's inward unit normal
  };
  std::vector<Sample> samples;
  samples.reserve(static_cast<std::size_t>(n));
  std::vector<EdgeSample> edge;
  double last_y = -1e9;
  for (int i = 0; i < n; ++i) {
    const cv::Point2f& a = contour[static_cast<std::size_t>((i + n - 1) % n)];
    const cv::Point2f& b = contour[static_cast<std::size_t>((i + 1) % n)];
    const cv::Point2f tan = b - a;
    const double len = std::hypot(tan.x, tan.y);
    if (len < 1e-6) continue;
    if (std::abs(tan.y) / len < min_sin) {
      // Along the epipolar lines: left to edge registration (below).
      edge.push_back({contour[static_cast<std::size_t>(i)],
                      cv::Point2f(static_cast<float>(tan.y / len), static_cast<float>(-tan.x / len))});
      continue;
    }
    const cv::Point2f& c = contour[static_cast<std::size_t>(i)];
    (void)last_y;
    const double y = c.y;
    std::vector<bool> lr, rr;
    const std::vector<double> lx = rowCrossings(f_.left_seg_.score, y, &lr);
    const std::vector<double> rx = rowCrossings(f_.right_seg_.score, y, &rr);
    // The left crossing this sample stands for: the nearest one.
    int li = -1;
    double best = 3.0;
    for (std::size_t k = 0; k < lx.size(); ++k)
      if (std::abs(lx[k] - c.x) < best) {
        best = std::abs(lx[k] - c.x);
        li = static_cast<int>(k);
      }
    if (li < 0) continue;
    const bool rising = lr[static_cast<std::size_t>(li)];
    Sample s;
    s.left = cv::Point2f(static_cast<float>(lx[static_cast<std::size_t>(li)]), static_cast<float>(y));
    s.normal = cv::Point2f(static_cast<float>(tan.y / len), static_cast<float>(-tan.x / len));  // inward
    // Order among the crossings of the same kind on both rows.
    int rank = 0, left_same = 0, right_same = 0;
    for (std::size_t k = 0; k < lx.size(); ++k)
      if (lr[k] == rising) {
        if (static_cast<int>(k) < li) ++rank;
        ++left_same;
      }
    int r_rank = 0;
    for (std::size_t k = 0; k < rx.size(); ++k) {
      if (rr[k] != rising) continue;
      ++right_same;
      const double d = s.left.x - rx[k];
      if (d >= minDisparity() && d <= maxDisparity()) {
        if (r_rank == rank) s.unique = static_cast<int>(s.cands.size());
        s.cands.push_back(d);
      }
      ++r_rank;
    }
    if (left_same != right_same) s.unique = -1;
    if (s.cands.size() == 1 && left_same == right_same) s.unique = 0;
    if (!s.cands.empty()) samples.push_back(std::move(s));
  }
  // Resolve ambiguous samples by continuity along the contour with the
  // unambiguous ones (order in `samples` follows the contour).
  const int m = static_cast<int>(samples.size());
  // Up to 8 samples either side, each counted once on a short contour.
  const int reach = std::min(8, (m - 1) / 2);
  for (int i = 0; i < m; ++i) {
    Sample& s = samples[static_cast<std::size_t>(i)];
    std::vector<double> near;
    for (int k = -reach; k <= reach; ++k) {
      if (k == 0) continue;
      const Sample& o = samples[static_cast<std::size_t>(((i + k) % m + m) % m)];
      if (o.unique >= 0) near.push_back(o.cands[static_cast<std::size_t>(o.unique)]);
    }
    double d = std::numeric_limits<double>::quiet_NaN();
    if (near.size() >= 3) {
      const double ref = median(near);
      double bestd = std::numeric_limits<double>::infinity();
      for (double c : s.cands)
        if (std::abs(c - ref) < bestd) {
          bestd = std::abs(c - ref);
          d = c;
        }
      // A sample disagreeing with its neighbours is more likely a wrong
      // crossing (or a rim seen differently) than a real jump.
      if (bestd > 3.0 * f_.params_.continuity_margin) d = std::numeric_limits<double>::quiet_NaN();
    } else if (s.unique >= 0) {
      d = s.cands[static_cast<std::size_t>(s.unique)];
    }
    if (!std::isfinite(d)) continue;
    Correspondence c;
    c.left = s.left;
    c.disparity = static_cast<float>(d);
    c.sigma = static_cast<float>(p.pixel_sigma * std::sqrt(2.0));
    c.source = Correspondence::Source::kContour;
    f_.vertices_.push_back(c);
    rim_normals_.push_back(s.normal);
  }
  if (p.edge_window > 0 && !edge.empty()) registerEdges(edge);
}

/// Step 2b: contour parts that run along the epipolar lines (the neck
/// base, a bottom edge) have no usable row crossings. Where an edge runs
/// parallel to the baseline both cameras see the same rim line (the
/// baseline lies in its tangent plane), so the edge's row as a function of
/// the column, y(x), is the same curve in both views shifted by the
/// disparity. Each such contour sample gets the shift that best aligns the
/// left curve with the right one over +-edge_window px, using only the
/// columns where the edge stays within min_crossing_angle of the rows
/// (where it turns steeper it is a flank's rim, a different line in each
/// view) (Gaussian weights;
/// quarter-pixel grid, then a parabola), within the disparities of the
/// row-crossing correspondences nearby (+-4 px), and is kept only where
/// the edge bends enough to fix it: the mean squared misalignment must
/// grow by edge_min_bend px^2 or more 2 px either side of the best shift,
/// and no other shift may come close (an ambiguous edge stays unmatched).
void CectFrameBuilder::registerEdges(const std::vector<EdgeSample>& edge) {
  const CectParams& p = f_.params_;
  const int W = static_cast<int>(std::lround(p.edge_window));
  // Zero crossings of every column, per view (the transposed score's rows).
  auto columns = [](const cv::Mat& score, std::vector<std::vector<double>>* ys,
                    std::vector<std::vector<bool>>* rising) {
    const cv::Mat t = score.t();
    ys->resize(static_cast<std::size_t>(t.rows));
    rising->resize(static_cast<std::size_t>(t.rows));
    for (int x = 0; x < t.rows; ++x)
      (*ys)[static_cast<std::size_t>(x)] = rowCrossings(t, x, &(*rising)[static_cast<std::size_t>(x)]);
  };
  std::vector<std::vector<double>> lys, rys;
  std::vector<std::vector<bool>> lrise, rrise;
  columns(f_.left_seg_.score, &lys, &lrise);
  columns(f_.right_seg_.score, &rys, &rrise);
  const std::size_t n_crossing = f_.vertices_.size();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double sw2 = 2.0 * (0.5 * W) * (0.5 * W);
  for (std::size_t e = 0; e < edge.size(); e += 2) {  // every other sample, as the rim profile
    const EdgeSample& es = edge[e];
    const bool down = es.normal.y > 0.0f;
    const int xi = cvRound(es.left.x);
    // Disparity range from the row-crossing correspondences nearby.
    double d_lo = std::numeric_limits<double>::infinity(), d_hi = -d_lo;
    for (std::size_t v = 0; v < n_crossing; ++v) {
      const cv::Point2f q = f_.vertices_[v].left - es.left;
      if (q.x * q.x + q.y * q.y > 9.0 * W * W) continue;
      d_lo = std::min(d_lo, static_cast<double>(f_.vertices_[v].disparity));
      d_hi = std::max(d_hi, static_cast<double>(f_.vertices_[v].disparity));
    }
    if (!std::isfinite(d_lo)) continue;  // no prior nearby: too risky on a flat edge
    d_lo = std::max(minDisparity(), d_lo - 4.0);
    d_hi = std::min(maxDisparity(), d_hi + 4.0);
    // The left curve over [xi - W, xi + W], the right one over the
    // columns those can shift to.
    std::vector<double> yl(static_cast<std::size_t>(2 * W + 1), nan);
    trackEdge(lys, lrise, xi, es.left.y, +1, W + 1, down, &yl, xi - W);
    trackEdge(lys, lrise, xi, es.left.y, -1, W + 1, down, &yl, xi - W);
    // Only the parts of the edge that run along the rows: where it turns
    // steeper it becomes a flank's rim, a different line in each view.
    const double max_slope = std::tan(p.min_crossing_angle * M_PI / 180.0);
    {
      std::vector<double> along(yl.size(), nan);
      for (std::size_t k = 1; k + 1 < yl.size(); ++k)
        if (std::abs(0.5 * (yl[k + 1] - yl[k - 1])) <= max_slope) along[k] = yl[k];  // NaN compares false
      yl.swap(along);
    }
    const int rx0 = static_cast<int>(std::floor(xi - W - d_hi)) - 1;
    const int rx1 = static_cast<int>(std::ceil(xi + W - d_lo)) + 1;
    std::vector<double> yr(static_cast<std::size_t>(rx1 - rx0 + 1), nan);
    const int rstart = cvRound(xi - 0.5 * (d_lo + d_hi));
    trackEdge(rys, rrise, rstart, es.left.y, +1, rx1 - rstart + 1, down, &yr, rx0);
    trackEdge(rys, rrise, rstart, es.left.y, -1, rstart - rx0 + 1, down, &yr, rx0);
    auto rightAt = [&](double x) {
      const double u = x - rx0;
      const int k = static_cast<int>(std::floor(u));
      if (k < 0 || k + 1 >= static_cast<int>(yr.size())) return nan;
      const double f = u - k;
      return (1.0 - f) * yr[static_cast<std::size_t>(k)] + f * yr[static_cast<std::size_t>(k + 1)];
    };
    double w_all = 0.0;
    for (int k = -W; k <= W; ++k) w_all += std::exp(-k * k / sw2);
    auto cost = [&](double d) {
      double c = 0.0, ws = 0.0;
      for (int k = -W; k <= W; ++k) {
        const double a = yl[static_cast<std::size_t>(k + W)];
        if (!std::isfinite(a)) continue;
        const double b = rightAt(xi + k - d);
        if (!std::isfinite(b)) continue;
        const double w = std::exp(-k * k / sw2);
        c += w * (a - b) * (a - b);
        ws += w;
      }
      return ws >= 0.6 * w_all ? c / ws : nan;
    };
    const double step = 0.25;
    std::vector<double> ds, cs;
    for (double d = d_lo; d <= d_hi + 1e-9; d += step) {
      ds.push_back(d);
      cs.push_back(cost(d));
    }
    int best = -1;
    for (std::size_t k = 0; k < cs.size(); ++k)
      if (std::isfinite(cs[k]) && (best < 0 || cs[k] < cs[static_cast<std::size_t>(best)])) best = static_cast<int>(k);
    if (best <= 0 || best + 1 >= static_cast<int>(cs.size())) continue;
    const double a = cs[static_cast<std::size_t>(best - 1)], b = cs[static_cast<std::size_t>(best)],
                 c = cs[static_cast<std::size_t>(best + 1)];
    if (!std::isfinite(a) || !std::isfinite(c)) continue;
    const double denom = a - 2.0 * b + c;
    const double d =
        ds[static_cast<std::size_t>(best)] + (denom > 0 ? std::clamp(0.5 * (a - c) / denom, -0.5, 0.5) * step : 0.0);
    const double c0 = cost(d), cm = cost(d - 2.0), cp = cost(d + 2.0);
    if (!std::isfinite(c0) || !std::isfinite(cm) || !std::isfinite(cp)) continue;
    const double bend = std::min(cm, cp) - c0;
    if (c0 > 1.0 || bend < p.edge_min_bend) continue;
    // Unique: every shift more than 2 px away is clearly worse.
    bool unique = true;
    for (std::size_t k = 0; k < cs.size() && unique; ++k)
      if (std::abs(ds[k] - d) > 2.0 && std::isfinite(cs[k]) && cs[k] < c0 + 0.5 * bend) unique = false;
    if (!unique) continue;
    const double y = yl[static_cast<std::size_t>(W)];
    if (!std::isfinite(y)) continue;
    Correspondence v;
    v.left = cv::Point2f(static_cast<float>(xi), static_cast<float>(y));
    v.disparity = static_cast<float>(d);
    // Weaker bends fix the shift less well.
    v.sigma = static_cast<float>(p.pixel_sigma * std::sqrt(2.0) * std::max(1.0, 1.0 / std::sqrt(bend)));
    v.source = Correspondence::Source::kEdge;
    f_.vertices_.push_back(v);
    rim_normals_.push_back(es.normal);
  }
}

/// Delaunay triangulation of the vertices, the triangle index map and the
/// triangles around each vertex.
void CectFrameBuilder::triangulate(double max_edge) {
  auto& V = f_.vertices_;
  f_.triangles_.clear();
  const cv::Rect rect(-1, -1, f_.left_rect_.cols + 2, f_.left_rect_.rows + 2);
  cv::Subdiv2D subdiv(rect);
  // getTriangleList returns the inserted coordinates exactly: look the
  // vertices up by them (the first of coincident vertices wins).
  std::unordered_map<std::uint64_t, int> vertex_at;
  auto key = [](float x, float y) {
    std::uint32_t bx, by;
    std::memcpy(&bx, &x, sizeof bx);
    std::memcpy(&by, &y, sizeof by);
    return (static_cast<std::uint64_t>(bx) << 32) | by;
  };
  for (std::size_t i = 0; i < V.size(); ++i) {
    subdiv.insert(V[i].left);
    vertex_at.emplace(key(V[i].left.x, V[i].left.y), static_cast<int>(i));
  }
  std::vector<cv::Vec6f> tris;
  subdiv.getTriangleList(tris);
  auto indexOf = [&](float x, float y) -> int {
    const auto it = vertex_at.find(key(x, y));
    return it == vertex_at.end() ? -1 : it->second;
  };
  const cv::Mat& mask = f_.left_seg_.mask;
  // Edge midpoints of border triangles sit on the border itself: they may
  // fall up to 1.5 px outside the mask.
  if (near_mask_.empty()) cv::dilate(mask, near_mask_, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
  for (const auto& t : tris) {
    const int a = indexOf(t[0], t[1]), b = indexOf(t[2], t[3]), c = indexOf(t[4], t[5]);
    if (a < 0 || b < 0 || c < 0) continue;
    // Only triangles inside the back: the centroid and the edge midpoints
    // must lie on the mask (the contour is concave at the neck and waist).
    const cv::Point2f pa = V[static_cast<std::size_t>(a)].left, pb = V[static_cast<std::size_t>(b)].left,
                      pc = V[static_cast<std::size_t>(c)].left;
    bool inside = true;
    for (const cv::Point2f& q : {(pa + pb + pc) / 3.0f, (pa + pb) * 0.5f, (pb + pc) * 0.5f, (pa + pc) * 0.5f}) {
      const int x = cvRound(q.x), y = cvRound(q.y);
      if (!(x >= 0 && y >= 0 && x < mask.cols && y < mask.rows && near_mask_.at<std::uint8_t>(y, x))) {
        inside = false;
        break;
      }
    }
    const double area = std::abs((pb.x - pa.x) * (pc.y - pa.y) - (pc.x - pa.x) * (pb.y - pa.y)) * 0.5;
    // Long edges bridge a gap in the correspondences (an unmatched edge
    // along the rows, a patch without seeds): a plane over it is a poor
    // guess; such pixels are better extrapolated from the seeds.
    if (max_edge > 0.0 && std::max({cv::norm(pa - pb), cv::norm(pb - pc), cv::norm(pa - pc)}) > max_edge)
      inside = false;
    if (inside && area > 0.5) f_.triangles_.emplace_back(a, b, c);
  }
  f_.vertex_triangles_.assign(V.size(), {});
  f_.triangle_index_.create(f_.left_rect_.size(), CV_32S);
  f_.triangle_index_.setTo(-1);
  for (std::size_t k = 0; k < f_.triangles_.size(); ++k) {
    const cv::Vec3i& t = f_.triangles_[k];
    for (int j = 0; j < 3; ++j) f_.vertex_triangles_[static_cast<std::size_t>(t[j])].push_back(static_cast<int>(k));
    // Rasterise with a small margin so that points on shared edges find a triangle.
    const cv::Point pts[3] = {cv::Point(cvRound(V[t[0]].left.x * 16), cvRound(V[t[0]].left.y * 16)),
                              cv::Point(cvRound(V[t[1]].left.x * 16), cvRound(V[t[1]].left.y * 16)),
                              cv::Point(cvRound(V[t[2]].left.x * 16), cvRound(V[t[2]].left.y * 16))};
    cv::fillConvexPoly(f_.triangle_index_, pts, 3, cv::Scalar(static_cast<int>(k)), cv::LINE_8, 4);
  }
}

}  // namespace massage_cell::cect
