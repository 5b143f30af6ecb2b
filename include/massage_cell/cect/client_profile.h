// A client's profile: what a therapist learnt about one subject's back,
// saved after a session and applied again in the next one. ROS-free
// (yaml-cpp).
//
// - c7_to_l4_m: C7 -> L4 along the body (metres) measured with both
//   landmarks given (clicks or skin markers). In a later session the layout's
//   own C7 -> L4 must agree within length_tolerance_m (TrustRules), else the
//   layout is refused: a landmark palpated a vertebra off, or another client.
// - corrections: per acupoint, where the therapist found it against the
//   model's layout, in the layout's own units so that they apply again to
//   any later layout of the same back (re-registered by its landmarks):
//   `along` a fraction of C7 -> L4 toward L4, `across_cun` cun toward the
//   subject's left.
//
// File (YAML), read strictly (docs/cect.md, "Client profiles"):
//   format: massage_cell/client_profile 1   # required, exactly this
//   client: "A. N. Other"            # required (may be ""): any id the therapist uses
//   c7_to_l4_m: 0.452                # optional, 0.2 .. 0.8 m
//   length_tolerance_m: 0.03         # optional (default 0.03), (0, 0.1] m
//   corrections:                     # optional: acupoint name -> {along, across_cun}, each optional (0)
//     BL23_L: {along: 0.012, across_cun: -0.2}
// Every other key, at the top or in a correction, is an error (a misspelt `c7_to_l4` would otherwise turn the
// length check off without a word), as is a value of the wrong type. `client` is required because a profile is one
// person's: the file must say whose it is so that the node's diagnostics and cect_locate's output show the therapist
// whose profile is in effect (the length check only catches another client whose back differs by more than the
// tolerance); the tools always write it, "" when no id was given.
#pragma once

#include <limits>
#include <map>
#include <string>

#include "massage_cell/cect/acupoint_model.h"

namespace massage_cell::cect {

struct LocatedAcupoints;  // locate.h

struct AcupointCorrection {
  double along = 0.0;       ///< fraction of C7 -> L4 toward L4, |along| <= 0.1
  double across_cun = 0.0;  ///< cun toward the subject's left, |across_cun| <= 1
};

struct ClientProfile {
  std::string client;
  double c7_to_l4_m = std::numeric_limits<double>::quiet_NaN();  ///< NaN: not measured
  double length_tolerance_m = 0.03;                              ///< ~ a vertebra's height at L1..L4 is 3.5 cm
  std::map<std::string, AcupointCorrection> corrections;
};

/// Reads a profile. Throws std::runtime_error "client profile '<path>': ..." naming the bad key: an unknown key
/// (with the known ones), a missing `format` or `client`, another format line, a value of the wrong type (a number
/// that is not one, `client` not a scalar, `corrections` or a correction not a map), a key given twice, a length
/// outside 0.2 .. 0.8 m, a correction beyond its limit; or that the file cannot be read or parsed.
ClientProfile loadClientProfile(const std::string& path);

/// One line for logs, diagnostics and tools: "'A. N. Other', C7 -> L4 0.452 m, 3 corrections" ("C7 -> L4 not
/// measured" without a length).
std::string describeClientProfile(const ClientProfile& profile);

/// Writes a profile (the format above). Throws std::runtime_error when the
/// file cannot be written, std::invalid_argument for values outside the limits.
void saveClientProfile(const ClientProfile& profile, const std::string& path);

/// The client's profile measured on one located pair: `base` (its corrections, its client unless `client` is not
/// empty) with the pair's C7 -> L4. Throws std::runtime_error saying why when the pair's C7 and L4 were not both
/// given (a click, ~set_landmark, --landmark, skin markers) or its layout was not trusted.
ClientProfile measuredProfile(const ClientProfile& base, const LocatedAcupoints& located, const std::string& client);

/// The model with the profile's corrections on its points. Throws
/// std::invalid_argument naming a correction for an acupoint the model does
/// not have.
AcupointModel withCorrections(const AcupointModel& model, const ClientProfile& profile);

}  // namespace massage_cell::cect
