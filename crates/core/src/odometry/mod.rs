//! Odometry: an EKF that fuses wheel odometry and an IMU into the planar `odom -> base_link` pose the
//! detector and the controller use (what robot_localization does on the paper's robot).
