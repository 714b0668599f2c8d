#pragma once
// The completeness plot of an injection-recovery run as SVG, written by hand (no toolkit in core): so the
// CLI writes it and the GUI (Qt Svg) can show it.
#include <string>
#include <vector>

#include "st/inject/recovery.hpp"

namespace st::inject {

/// An SVG document (640 x 440 px): completeness (recovered fraction) against expected SNR, one point per
/// non-empty bin at the mean expected SNR of its objects with a horizontal bar over the bin's extent and a
/// vertical Wilson 68% binomial error bar; the counts "k/n" above each point; axes from 0 to a round
/// maximum with ticks, labelled "expected SNR (optimal matched filter, whole track)" and "completeness
/// (fraction recovered)"; `title` on top (escaped). Well-formed XML.
std::string completenessSvg(const std::vector<CompletenessBin>& bins, const std::string& title);

/// `text` with &, <, >, " and ' escaped for XML.
std::string xmlEscape(const std::string& text);

}  // namespace st::inject
