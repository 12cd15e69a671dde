"""Static pictures: model figures and cross-section plots."""
