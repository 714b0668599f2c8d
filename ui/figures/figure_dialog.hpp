#pragma once
// "Export figure…": any image view of the window (the central view, the inspector's stamps, …) or any plot
// (the velocity map, profiles, …), any row of stamps (the candidate's stamps and segment strip, the fit's
// data | model | residual), or the preset of the paper's figure fig_st_sky_and_nea for the selected
// candidate, to PNG at a chosen DPI, SVG or PDF (figure_export.hpp). Image figures get a colour bar with its
// units, a scale bar in arcsec when the plate scale is known, a N/E compass when the observation has a WCS,
// a title and axis labels (figure_render.hpp). Stacking and painting run on a worker thread; plots are
// captured on the GUI thread (cheap) and replayed in the worker.
#include <QDialog>
#include <QFutureWatcher>
#include <QPointer>
#include <functional>
#include <memory>
#include <vector>

#include "core_services.hpp"
#include "figure_export.hpp"
#include "figure_render.hpp"
#include "observation.hpp"

class QCheckBox;
class QComboBox;
class QDoubleSpinBox;
class QLabel;
class QLineEdit;
class QPushButton;
class QSpinBox;
class QCustomPlot;

namespace st::ui {

class ImageView;
class StampStrip;

class FigureDialog : public QDialog {
  Q_OBJECT
 public:
  /// What the dialog needs from the window.
  struct Context {
    Observation* observation = nullptr;
    QWidget* root = nullptr;       ///< image views and plots are found among its children
    ImageView* central = nullptr;  ///< listed first, as "Central view"
    /// The cube live stacks use (filtered or unfiltered, as the inspector chose), for the preset.
    std::function<std::shared_ptr<const search::FilteredCube>()> stackCube;
    /// CoreServices::pixelToSky, for the compass (may be empty).
    std::function<std::optional<std::pair<double, double>>(const FrameCube&, double, double)> pixelToSky;
    /// The candidates selected in the candidates table (indices into the result, in the table's order), for
    /// the sheet of selected candidates (may be empty).
    std::function<std::vector<int>()> selectedCandidates;
  };

  explicit FigureDialog(Context context, QWidget* parent = nullptr);

  /// Re-lists the views and plots (called when shown).
  void refreshSources();
  /// Names of the sources as listed: views, plots, stamp strips, the two candidate sheets (selected in
  /// the table, shown by its filters) when there is a search result, the preset last.
  [[nodiscard]] QStringList sourceNames() const;
  /// Chooses source `index` (in sourceNames()); the title and units are filled in from it.
  void setSource(int index);
  [[nodiscard]] int presetIndex() const;
  /// Index of the sheet of the candidates selected in the table (`shown` false) or of all the candidates the
  /// table's filters (label, SNR, false alarms, flags) show (`shown` true); -1 without a search result.
  [[nodiscard]] int sheetIndex(bool shown) const;
  /// Half size of the preset's and the sheet's stamps, px.
  void setStampHalfSize(int px);
  /// Size and resolution (height 0 = from the figure's aspect ratio).
  void setFigureSize(const FigureSize& size);
  void setTitle(const QString& title);
  /// Starts writing `path` (format from its suffix) in a worker. False when an export is running or nothing
  /// can be exported (the reason is in lastMessage(), and exportFinished is emitted with it).
  bool exportTo(const QString& path);
  [[nodiscard]] bool busy() const { return m_watcher.isRunning(); }
  [[nodiscard]] QString lastMessage() const;

 signals:
  /// An export ended; `message` names the path and, on failure, why.
  void exportFinished(const QString& path, bool ok, const QString& message);

 protected:
  void showEvent(QShowEvent* event) override;

 private:
  struct Source {
    QString name;
    QPointer<ImageView> view;
    QPointer<QCustomPlot> plot;
    bool preset = false;
    QPointer<StampStrip> strip;  ///< a row of stamps (candidate stamps, segments, the fit's data/model/residual)
    enum class Sheet { None, Selected, Shown } sheet = Sheet::None;  ///< a sheet of several candidates
  };
  void buildUi();
  void onSourceChanged();
  void onFinished();
  /// The whole export of `source` to `path`, to run in the worker; empty with `error` set when impossible.
  std::function<void()> makeJob(const Source& source, const QString& path, QString& error);
  /// Builds the figure of a view (cropping happens in the worker).
  std::function<ImageFigure()> imageBuilder(const ImageView& view);
  std::function<ImageFigure()> presetBuilder(QString& error);
  /// One panel per tile of `strip`, on the strip's shared display limits, captioned
  /// with the selected candidate's SNR and motion relative to the stars (motion_vs_sky.hpp).
  std::function<ImageFigure()> stripBuilder(const StampStrip& strip);
  /// The grid of per-candidate stamps (candidate_sheet.hpp) of the selected or shown candidates.
  std::function<ImageFigure()> sheetBuilder(Source::Sheet which, QString& error);
  /// Indices of the candidates a sheet shows, in order.
  [[nodiscard]] std::vector<int> sheetCandidates(Source::Sheet which) const;
  [[nodiscard]] std::optional<Compass> compassNear(double x, double y) const;
  [[nodiscard]] FigureSize figureSize() const;

  Context m_ctx;
  std::vector<Source> m_sources;
  QComboBox* m_source = nullptr;
  QLineEdit* m_title = nullptr;
  QLineEdit* m_units = nullptr;
  QLineEdit* m_xLabel = nullptr;
  QLineEdit* m_yLabel = nullptr;
  QCheckBox* m_colourBar = nullptr;
  QCheckBox* m_scaleBar = nullptr;
  QCheckBox* m_compass = nullptr;
  QCheckBox* m_axes = nullptr;
  QCheckBox* m_crop = nullptr;
  QDoubleSpinBox* m_width = nullptr;
  QDoubleSpinBox* m_height = nullptr;
  QSpinBox* m_dpi = nullptr;
  QSpinBox* m_stampHalf = nullptr;
  QLineEdit* m_path = nullptr;
  QPushButton* m_export = nullptr;
  QLabel* m_status = nullptr;
  QFutureWatcher<QString> m_watcher;
  QString m_runningPath;
  int m_presetHalf = 40;  ///< the stamp half size chosen for the preset and for the sheets, kept apart
  int m_sheetHalf = 12;
};

}  // namespace st::ui
