"""Online estimation: the EKF over slip-model parameters and its scenarios."""
