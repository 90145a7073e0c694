"""Tuning of the navigation filter, named after the PX4 EKF2 parameters they mirror."""

from __future__ import annotations

from dataclasses import dataclass

NS_PER_S = 1_000_000_000


@dataclass(frozen=True, slots=True, kw_only=True)
class NavParams:
    """Noise densities, gates, rates and timeouts (1-sigma figures)."""

    # Prediction. The IMU is downsampled to the filter rate (EKF2_PREDICT_US) and the
    # covariance is propagated every ``cov_every`` filter steps with the summed deltas.
    filter_period_ns: int = 20_000_000  # 50 Hz delayed-state prediction
    cov_every: int = 4  # covariance at 12.5 Hz (25 Hz measured no better)
    gyro_noise_rad_s: float = 0.015  # EKF2_GYR_NOISE (the sensor's 0.003 plus model error)
    accel_noise_m_s2: float = 0.15  # EKF2_ACC_NOISE is 0.35; our IMU is 0.05 per sample
    gyro_bias_noise_rad_s2: float = 1.0e-4  # EKF2_GYR_B_NOISE
    accel_bias_noise_m_s3: float = 3.0e-3  # EKF2_ACC_B_NOISE
    wind_noise_m_s2: float = 0.05  # EKF2_WIND_NSD
    imu_period_ns: int = 5_000_000  # nominal IMU sample period (noise per sample)

    # Initial uncertainty.
    init_pos_m: float = 3.0
    init_vel_m_s: float = 1.0
    init_tilt_rad: float = 0.1
    init_yaw_rad: float = 0.3
    init_gyro_bias_rad_s: float = 0.005
    init_accel_bias_m_s2: float = 0.1
    init_wind_m_s: float = 5.0
    align_samples: int = 20  # IMU samples averaged for tilt alignment

    # Delayed fusion horizon (EKF2 fuses on a delayed time horizon with an output predictor).
    fusion_horizon_ns: int = 500_000_000

    # GNSS (EKF2_GPS_*): noise floors; the receiver's eph/epv are used when larger.
    gnss_pos_noise_m: float = 0.5
    gnss_vel_noise_m_s: float = 0.1  # EKF2_GPS_V_NOISE; our receiver: 0.1 (GpsFix has no sacc)
    gnss_pos_gate: float = 5.0
    gnss_vel_gate: float = 5.0
    gnss_timeout_ns: int = 1_000_000_000  # no fix for this long: GNSS lost, dead-reckoning
    gnss_reset_timeout_ns: int = 5_000_000_000

    # Barometer: the height reference (EKF2_HGT_REF baro); its offset tracks GNSS height.
    baro_noise_m: float = 1.0
    baro_gate: float = 5.0
    baro_bias_noise_m_sqrt_s: float = 0.05
    baro_timeout_ns: int = 1_000_000_000
    baro_reset_timeout_ns: int = 5_000_000_000

    # Airspeed (EKF2_EAS_NOISE, EKF2_TAS_GATE) and synthetic sideslip (EKF2_FUSE_BETA).
    airspeed_noise_m_s: float = 1.4
    airspeed_gate: float = 5.0
    airspeed_min_m_s: float = 5.0  # below this the aircraft is not flying: no fusion
    beta_noise_rad: float = 0.3  # EKF2_BETA_NOISE
    beta_gate: float = 5.0
    fuse_beta: bool = True

    # Magnetic heading (EKF2_MAG_TYPE heading; EKF2_HEAD_NOISE, EKF2_MAG_DECL).
    heading_noise_rad: float = 0.1
    heading_gate: float = 5.0
    mag_declination_rad: float = 0.0

    # External position aids (EKF2_EV_CTRL bit 0, EKF2_EVP_NOISE, EKF2_EVP_GATE).
    aid_sigma_m: float = 5.0  # used when a measurement has neither cov nor sigma
    aid_noise_floor_m: float = 0.5
    aid_gate: float = 5.0
    aid_min_interval_ns: int = 10_000_000  # at most 100 Hz per aid: a flood is rejected
    aid_timeout_ns: int = 1_000_000_000  # no measurement for this long: the aid is lost
    aid_reset_timeout_ns: int = 5_000_000_000  # EKF2 reset on rejection timeout
    aid_buffer_len: int = 64

    @property
    def filter_period_s(self) -> float:
        return self.filter_period_ns / NS_PER_S
