#include "fits_file.hpp"

#include <algorithm>
#include <filesystem>
#include <memory>

#include "st/common/error.hpp"

namespace st::io::detail {

std::string cfitsioMessage(int status) {
  char text[FLEN_STATUS] = {};
  fits_get_errstatus(status, text);
  std::string out = text;
  char msg[FLEN_ERRMSG] = {};
  std::string stack;
  while (fits_read_errmsg(msg) != 0) {
    if (!stack.empty()) stack += "; ";
    stack += msg;
  }
  if (!stack.empty()) out += " (" + stack + ")";
  return out;
}

FitsFile FitsFile::openRead(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw InputError(path + ": file not found");
  if (std::filesystem::is_directory(path, ec)) throw InputError(path + ": is a folder, not a FITS file");
  fitsfile* f = nullptr;
  int status = 0;
  fits_open_diskfile(&f, path.c_str(), READONLY, &status);
  if (status != 0) {
    const std::string text = cfitsioMessage(status);
    if (f != nullptr) {
      int s2 = 0;
      fits_close_file(f, &s2);
    }
    throw FitsError(path + ": not a readable FITS file: " + text);
  }
  return FitsFile(f, path);
}

FitsFile FitsFile::create(const std::string& path) {
  std::error_code ec;
  std::filesystem::remove(path, ec);
  fitsfile* f = nullptr;
  int status = 0;
  fits_create_diskfile(&f, path.c_str(), &status);
  if (status != 0) throw FitsError(path + ": cannot create FITS file: " + cfitsioMessage(status));
  return FitsFile(f, path);
}

FitsFile::FitsFile(FitsFile&& other) noexcept : m_fptr(other.m_fptr), m_path(std::move(other.m_path)) {
  other.m_fptr = nullptr;
}

FitsFile::~FitsFile() {
  if (m_fptr != nullptr) {
    int status = 0;
    fits_close_file(m_fptr, &status);
    if (status != 0) fits_clear_errmsg();
  }
}

int FitsFile::currentHdu() const {
  int n = 0;
  fits_get_hdu_num(m_fptr, &n);
  return n;
}

void FitsFile::check(int status, const std::string& what) const {
  if (status == 0) return;
  throw FitsError(m_path + " HDU " + std::to_string(currentHdu()) + ": " + what + ": " +
                  cfitsioMessage(status));
}

void FitsFile::close() {
  if (m_fptr == nullptr) return;
  int status = 0;
  fits_close_file(m_fptr, &status);
  m_fptr = nullptr;
  if (status != 0) throw FitsError(m_path + ": closing the file: " + cfitsioMessage(status));
}

FitsHeader readHeader(const FitsFile& file) {
  char* text = nullptr;
  int ncards = 0;
  int status = 0;
  fits_convert_hdr2str(file.get(), 0, nullptr, 0, &text, &ncards, &status);
  std::unique_ptr<char, void (*)(char*)> owner(text, [](char* p) {
    int s = 0;
    if (p != nullptr) fits_free_memory(p, &s);
  });
  file.check(status, "reading the header");
  return parseHeaderText(text, ncards);
}

FitsHeader parseHeaderText(const char* text, int ncards) {
  FitsHeader header;
  header.cards.reserve(static_cast<std::size_t>(ncards));
  for (int i = 0; i < ncards; ++i) {
    char card[FLEN_CARD] = {};
    std::copy_n(text + static_cast<std::size_t>(i) * 80, 80, card);
    FitsCard c;
    char name[FLEN_KEYWORD] = {};
    int len = 0;
    int status = 0;
    fits_get_keyname(card, name, &len, &status);
    c.key = name;
    if (c.key == "END") break;
    if (c.key.empty() || c.key == "COMMENT" || c.key == "HISTORY" || std::string_view(card + 8, 2) != "= ") {
      std::string rest(card + std::min<std::size_t>(8, std::char_traits<char>::length(card)));
      rest.erase(rest.find_last_not_of(' ') + 1);
      c.comment = rest;
      header.cards.push_back(std::move(c));
      continue;
    }
    char value[FLEN_VALUE] = {};
    char comment[FLEN_COMMENT] = {};
    status = 0;
    fits_parse_value(card, value, comment, &status);
    if (status != 0) {
      fits_clear_errmsg();
      continue;  // an unparsable card carries no usable value; drop it rather than fail the whole file
    }
    std::string v = value;
    if (v.size() >= 2 && v.front() == '\'') {
      c.isString = true;
      v = v.substr(1, v.size() - 2);
      std::string unq;
      for (std::size_t k = 0; k < v.size(); ++k) {
        unq += v[k];
        if (v[k] == '\'' && k + 1 < v.size() && v[k + 1] == '\'') ++k;
      }
      unq.erase(unq.find_last_not_of(' ') + 1);
      v = unq;
    }
    c.value = v;
    c.comment = comment;
    header.cards.push_back(std::move(c));
  }
  return header;
}

}  // namespace st::io::detail
