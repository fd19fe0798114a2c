"""A priori standard deviations shared by the engine's packages (adjustment, intersection, measurement)."""

#: a priori sigma of an image measurement, px
IMAGE_SIGMA = 0.5
