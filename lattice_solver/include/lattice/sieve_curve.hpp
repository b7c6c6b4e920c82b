#pragma once
// Aggregate grading: the volume fraction of aggregate passing a sieve of opening d, P(d), between the
// smallest and the largest diameter of the curve (P(d_min) = 0, P(d_max) = 1 after normalisation).
// Either Fuller's curve P(d) = (d/d_max)^q (q = 0.5 by default; Fuller & Thompson 1907), truncated to
// [d_min, d_max], or a table of (d, P) points interpolated linearly.

#include <random>
#include <vector>

namespace lattice {

class SieveCurve {
 public:
  /// Fuller curve between dMin and dMax (0 < dMin < dMax), sampled as `classes` geometric sieve classes.
  static SieveCurve fuller(double dMin, double dMax, double exponent = 0.5, int classes = 12);
  /// A table: strictly increasing diameters [m] and non-decreasing passing fractions; at least two rows,
  /// the first passing value below the last. Throws std::invalid_argument naming the offending row.
  static SieveCurve table(std::vector<double> diameters, std::vector<double> passing);

  double minDiameter() const { return d_.front(); }
  double maxDiameter() const { return d_.back(); }
  /// Normalised passing fraction at d (0 below d_min, 1 above d_max).
  double passing(double d) const;

  /// Diameters whose sphere volumes total `volume` [m³] with the curve's grading, largest first: each
  /// sieve class gets its share (P(d_hi) − P(d_lo)) × volume, filled with diameters drawn uniformly in
  /// the class until the next one would overshoot by more than half its volume.
  std::vector<double> sample(double volume, std::mt19937_64& rng) const;

 private:
  std::vector<double> d_, p_;  // class bounds and normalised passing fractions
};

}  // namespace lattice
