#pragma once
// The building blocks of a self-contained HTML page (`emcalign report`): text escaped,
// figures inline (PNG as data: URIs), tables, a correlation heat map, and the page with its
// styles inline. Nothing on the page refers to anything outside it: no scripts, no fonts,
// no style sheets, no images by URL; it reads offline and prints (A4, figures kept whole).

#include <string>
#include <string_view>
#include <vector>

#include "emcalign/core/result.hpp"

namespace emcalign::report::html {

/// Text safe inside an element or an attribute value (&, <, >, " and ' escaped).
std::string escape(std::string_view text);
/// RFC 4648 base64 with padding.
std::string base64(std::string_view bytes);
/// A PNG file as a data: URI; fails when the file cannot be read or is not a PNG.
Result<std::string> pngDataUri(const std::string& path);
/// A <figure> holding the PNG inline, with its caption (plain text, escaped).
Result<std::string> figure(const std::string& pngPath, const std::string& caption);

/// A table; the cells are HTML (escape text first). `numeric` columns are right-aligned.
struct Table {
  std::string caption = {};
  std::vector<std::string> header = {};
  std::vector<std::vector<std::string>> rows = {};
  std::vector<bool> numeric = {};          ///< per column (missing: text)
  std::vector<std::string> rowClass = {};  ///< per row, a class of the page's styles ("warn", "sub"), or ""
};
std::string table(const Table& t);

/// A matrix of values in [−1, 1] (a correlation matrix) as a table whose cells are coloured
/// from blue (−1) through white (0) to red (+1), each with its value to two decimals.
std::string heatMap(const std::vector<std::string>& labels, const std::vector<std::vector<double>>& matrix,
                    const std::string& caption);

/// A paragraph of plain text.
std::string paragraph(std::string_view text);
/// A list of plain-text items (class "warn" marks warnings).
std::string list(const std::vector<std::string>& items, std::string_view cssClass = {});

struct Section {
  std::string id;     ///< anchor of the contents
  std::string title;  ///< plain text
  std::string body;   ///< HTML
};

/// The whole page: its title, a line under it (plain text), the contents, the sections and
/// a footer (plain text; none when empty).
std::string page(const std::string& title, const std::string& subtitle, const std::vector<Section>& sections,
                 const std::string& footer = {});

}  // namespace emcalign::report::html
