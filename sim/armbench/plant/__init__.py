"""Plant models for the arm bench: the PCA9685 PWM board, MG996R servos and the arm itself."""
