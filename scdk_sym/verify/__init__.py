"""Cross-checks of a model against independent references (Pinocchio, MuJoCo)."""
