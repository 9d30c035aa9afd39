"""The command line's names for the API's options: what flag sets an option (for messages), and
the flags that set one calibration field each. The parser defines the flags with them; the
commands and the error messages read them."""

from __future__ import annotations

__all__ = ["flag_for", "CALIBRATION_FLAGS"]

#: Options whose command-line name is not ``--`` + the option name with dashes.
_FLAGS = {"real": "REAL", "sim": "SIM", "real_mtf": "--real-mtf/--real-edge", "sim_mtf": "--sim-mtf/--sim-edge",
          "real_mrtd": "--real-bars", "sim_mrtd": "--sim-bars",
          "psnr_anchors": "--config", "ssim_exponents": "--config", "grades": "--config",
          "mtf_options": "--config", "sitf_options": "--config", "mrtd_options": "--config",
          "transfer_options": "--config", "tolerances": "--tolerance",
          "register": "--register", "client": "--workers", "chunk_size": "--workers", "relative_humidity": "--humidity",
          "max_bytes": "--max-memory"}

#: Flags that override one calibration field (``ScoringConfig.calibration``): flag dest -> (field,
#: metavar, help).
CALIBRATION_FLAGS = {
    "emissivity": ("emissivity", "E", "the object's emissivity, in (0, 1]"),
    "reflected_temperature": ("reflected_temperature", "DEGC", "reflected apparent temperature, °C"),
    "atmospheric_temperature": ("atmospheric_temperature", "DEGC", "air temperature, °C"),
    "object_distance": ("object_distance", "M", "distance to the object, metres"),
    "humidity": ("relative_humidity", "PERCENT", "relative humidity, percent"),
}


def flag_for(option: str | None) -> str | None:
    """The command-line flag (or argument) that sets an API option."""
    if option is None:
        return None
    return _FLAGS.get(option, "--" + option.replace("_", "-"))
