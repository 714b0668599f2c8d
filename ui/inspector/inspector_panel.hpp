#pragma once
// The stack inspector: IPSA/CSA at the current velocity, filtered or unfiltered frames, "tracking the sky"
// beside "tracking the candidate" around the selected point (the paper's figure fig_st_sky_and_nea: the
// asteroid streaks in one and is sharp in the other), and the radial profile at a point with its Moffat fit
// and FWHM. Stamps are computed by the shared StackScrubber (tags kSkyTag / kTrackTag).
#include <QFutureWatcher>
#include <QWidget>
#include <memory>

#include "core_services.hpp"
#include "image_view.hpp"
#include "observation.hpp"
#include "stack_scrubber.hpp"

class QCustomPlot;
class QLabel;
class QRadioButton;
class QCheckBox;

namespace st::ui {

class InspectorPanel : public QWidget {
  Q_OBJECT
 public:
  static constexpr int kSkyTag = 11;
  static constexpr int kTrackTag = 12;
  static constexpr int kStampHalf = 40;  ///< stamps are (2 * kStampHalf + 1)^2 pixels

  InspectorPanel(Observation* observation, StackScrubber* scrubber, const CoreServices* services,
                 QWidget* parent = nullptr);

  /// The cube stacks use: filtered (default) or the unfiltered frames when available and chosen.
  [[nodiscard]] std::shared_ptr<const search::FilteredCube> stackCube() const;
  /// Centre of the stamps and of the profile (image pixel).
  void setPoint(double x, double y);
  /// Fits the radial profile at (x, y) of `image` in a worker; shows it when done. (offsetX, offsetY) is
  /// added to the positions shown (a stamp's corner in the full image).
  void showProfile(std::shared_ptr<const Image> image, double x, double y, double offsetX = 0,
                   double offsetY = 0);
  [[nodiscard]] bool useUnfiltered() const;

 signals:
  void cubeChoiceChanged();

 private:
  void requestStamps();
  void onStack(const std::shared_ptr<const Image>& image, const StackRequest& req);
  std::shared_ptr<const Image> cutout(const Image& full) const;

  Observation* m_obs;
  StackScrubber* m_scrubber;
  const CoreServices* m_services;
  QRadioButton* m_ipsa;
  QRadioButton* m_csa;
  QCheckBox* m_unfiltered;
  ImageView* m_skyView;
  ImageView* m_trackView;
  QLabel* m_skyLabel;
  QLabel* m_trackLabel;
  QCustomPlot* m_profile;
  QLabel* m_profileLabel;
  QFutureWatcher<ProfileFit> m_profileWatcher;
  QPointF m_profileOffset;
  double m_px = -1;
  double m_py = -1;
};

}  // namespace st::ui
