"""External loads (plates assigned to feet), inverse dynamics and pelvis residuals, the
inertial-parameter
regressors and the subject's mass distribution identified from them."""

__all__: list[str] = []
