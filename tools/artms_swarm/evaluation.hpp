// Evaluation of a run against truth (the launcher, after every process has
// exited; truth only ever reaches this step). Reads truth.oem, nav/<id>.csv
// and nav/targets.csv; writes eval/observers.csv and eval/targets.csv (the
// inputs of artms-report) and returns the per-target summary figures.
//
// Errors are estimate - truth. Target errors are in a_o * ROE meters with the
// truth observer's a_o; truth ROE are the osculating quasi-nonsingular ROE of
// the true states (the filter estimates osculating elements too).
//
// Summary figures per observer and target (docs/sod.md, "Evaluation"):
//  * final_range_m, final_dlambda_error_pct, final_dlambda_sigma_pct: at the
//    last navigation step, in % of the true range;
//  * convergence_orbits: the first time (in orbits of the reference period)
//    after which the a*dlambda error stays within 1 % of range to the end
//    (null if it never does);
//  * frac_within_3sigma: per ROE, the fraction of steps after convergence
//    (after half the run if it never converged) with |error| <= 3 sigma;
//  * nees_mean and nees_within_95: mean NEES of the 6 ROE after
//    convergence, and the fraction of those steps inside the two-sided 95 %
//    chi-square band for 6 degrees of freedom [1.237, 14.449];
//  * local_measurements, remote_measurements: the filter's final counts.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "artms/config/scenario.hpp"

namespace artms::swarm {

// One line of the run folder's CSV files split on `sep` (no quoting there).
std::vector<std::string> split_csv(const std::string& line, char sep = ',');

// Fills summary["observers"][id]["targets"] and ["period_s"]; never throws
// for missing or malformed files (the figures it cannot compute are null).
void evaluate_run(const config::Scenario& sc, const std::filesystem::path& dir, nlohmann::json& summary);

}  // namespace artms::swarm
