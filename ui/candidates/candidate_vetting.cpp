#include "candidate_vetting.hpp"

#include <Qt>

namespace st::ui {

using session::ArtifactReason;
using session::Label;

std::optional<VettingKey> vettingKeyFor(int key) noexcept {
  switch (key) {
    case Qt::Key_R:
      return VettingKey{Label::Real, ArtifactReason::None};
    case Qt::Key_U:
      return VettingKey{Label::Unsure, ArtifactReason::None};
    case Qt::Key_C:
      return VettingKey{Label::Artifact, ArtifactReason::ChargeLeakage};
    case Qt::Key_D:
      return VettingKey{Label::Artifact, ArtifactReason::Diffraction};
    case Qt::Key_X:
      return VettingKey{Label::Artifact, ArtifactReason::CosmicRay};
    case Qt::Key_G:
      return VettingKey{Label::Artifact, ArtifactReason::Ghost};
    case Qt::Key_O:
      return VettingKey{Label::Artifact, ArtifactReason::Other};
    case Qt::Key_0:
    case Qt::Key_Backspace:
    case Qt::Key_Delete:
      return VettingKey{Label::Unvetted, ArtifactReason::None};
    default:
      return std::nullopt;
  }
}

QString vettingShortcutHelp() {
  return "<b>Vetting keys</b> (candidates table focused): label the selected candidate and go to the next "
         "unvetted one.<table>"
         "<tr><td><b>R</b></td><td>real</td></tr>"
         "<tr><td><b>U</b></td><td>unsure</td></tr>"
         "<tr><td><b>C</b></td><td>artifact: charge leakage (bleed trail, saturated column)</td></tr>"
         "<tr><td><b>D</b></td><td>artifact: diffraction spike / bright-star halo</td></tr>"
         "<tr><td><b>X</b></td><td>artifact: cosmic ray</td></tr>"
         "<tr><td><b>G</b></td><td>artifact: ghost</td></tr>"
         "<tr><td><b>O</b></td><td>artifact: other</td></tr>"
         "<tr><td><b>0</b>, <b>Backspace</b></td><td>clear the label</td></tr>"
         "<tr><td><b>N</b>, double click</td><td>edit the note (Enter saves, Esc cancels)</td></tr>"
         "<tr><td><b>↑ ↓</b></td><td>previous / next candidate</td></tr>"
         "</table>Every change is saved to the session file at once.";
}

QString labelText(Label label) {
  return label == Label::Unvetted ? QString() : QString::fromLatin1(session::toString(label));
}

QString reasonText(ArtifactReason reason) {
  return QString::fromLatin1(session::toString(reason)).replace('_', ' ');
}

QColor labelColour(Label label, bool strong) {
  const int alpha = strong ? 200 : 60;
  switch (label) {
    case Label::Real:
      return QColor(40, 170, 70, alpha);
    case Label::Artifact:
      return QColor(210, 50, 50, alpha);
    case Label::Unsure:
      return QColor(230, 190, 30, alpha);
    default:
      return {};
  }
}

}  // namespace st::ui
