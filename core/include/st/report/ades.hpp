#pragma once
// ADES documents (IAU Astrometry Data Exchange Standard, version 2022: IAU-ADES/ADES-Master, "ADES
// Description"), held once and written in either of its two spellings:
//   XML: <ades version="2022"><obsBlock><obsContext>…</obsContext><obsData><optical>…</optical>…</obsData>
//        </obsBlock></ades>, what submit.xsd validates;
//   PSV: the first line "# version=2022"; every obsContext element a '#' line ("# telescope"), its
//        sub-elements '!' lines ("! aperture 0.50"); then one '|'-separated line of field names and one line
//        of values per observation, blanks around values allowed, an empty value = an absent element.
// A PSV file is valid when its XML equivalent validates (ADES Description); adesXmlFromPsv() is that
// equivalent, as the ADES-Master psvtoxml builds it, except that it keeps the PSV's field order (psvtoxml
// reorders the fields into the schema's), so that a validation also checks the order we write.
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace st::report {

inline constexpr const char* kAdesVersion = "2022";

/// One obsContext element: observatory, submitter, observers, measurers, telescope, software, comment, ...
/// `text` is the element's own text (rarely used: "# fundingSource NASA"); `items` its sub-elements in order,
/// e.g. {"mpcCode", "291"} or {"name", "A. Smith"} (repeated for several names).
struct AdesContextBlock {
  std::string name;
  std::string text;
  std::vector<std::pair<std::string, std::string>> items;
};

/// One obsBlock of optical observations: its context, the field names in order (schema order: trkSub, mode,
/// stn, obsTime, ra, dec, rmsRA, rmsDec, astCat, mag, band, logSNR, remarks) and one row of values per
/// observation ("" = the element is absent for that observation).
struct AdesDocument {
  std::string version = kAdesVersion;
  std::vector<AdesContextBlock> context;
  std::vector<std::string> fields;
  std::vector<std::vector<std::string>> rows;
};

/// The PSV text; columns padded to a common width. Throws st::InputError for a row whose length differs from
/// the fields', or for a name or value holding '|' or a line break.
[[nodiscard]] std::string adesPsvText(const AdesDocument& document);
/// The XML text (UTF-8, with the XML declaration; & < > " ' escaped). Same errors as adesPsvText.
[[nodiscard]] std::string adesXmlText(const AdesDocument& document);
/// Reads a PSV text of one obsBlock of optical observations. Throws st::InputError naming the line (1-based)
/// for: a first line that is not "# version=…", a '!' line before any '#' line, a second obsBlock, a data
/// line with more values than there are field names, no field-name line. A data line with fewer values than
/// names leaves the rest absent (as psvtoxml does).
[[nodiscard]] AdesDocument parseAdesPsv(std::string_view psv);
/// adesXmlText(parseAdesPsv(psv)).
[[nodiscard]] std::string adesXmlFromPsv(std::string_view psv);

}  // namespace st::report
