//! [`ValidConfig`]: a [`Config`] that has passed [`Config::validate`], so a stage that
//! takes one never sees a knob out of its range.

use serde::{Deserialize, Serialize};

use super::{Config, ConfigError, Preset};

/// A config whose every knob is within its range: only validation makes one
/// ([`Config::validated`], [`super::Layers::build`], deserialising, which validates), and
/// it is read-only (it derefs to [`Config`]; [`ValidConfig::into_config`] gives the
/// config back to change it, and validating it again gives a new one).
///
/// What a knob becomes at a recording's sampling (a blur kernel in pixels) is checked
/// once the recording is known, by [`Config::validate_for`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(into = "Config", try_from = "Config")]
pub struct ValidConfig(Config);

impl ValidConfig {
    /// The parameters of `preset`: every preset is valid (its test holds them to
    /// [`Config::validate`]), so this one needs no check.
    pub fn preset(preset: Preset) -> Self {
        ValidConfig(Config::preset(preset))
    }

    /// A config that has just passed [`Config::validate`].
    pub(super) fn checked(config: Config) -> Self {
        ValidConfig(config)
    }

    /// The config, to read.
    pub fn config(&self) -> &Config {
        &self.0
    }

    /// The config, to change (and validate again).
    pub fn into_config(self) -> Config {
        self.0
    }
}

impl Default for ValidConfig {
    /// The default preset's parameters ([`Config::default`]).
    fn default() -> Self {
        ValidConfig::preset(Preset::default())
    }
}

impl std::ops::Deref for ValidConfig {
    type Target = Config;

    fn deref(&self) -> &Config {
        &self.0
    }
}

impl AsRef<Config> for ValidConfig {
    fn as_ref(&self) -> &Config {
        &self.0
    }
}

impl From<ValidConfig> for Config {
    fn from(valid: ValidConfig) -> Config {
        valid.0
    }
}

impl TryFrom<Config> for ValidConfig {
    type Error = ConfigError;

    /// [`Config::validated`].
    fn try_from(config: Config) -> Result<Self, ConfigError> {
        config.validated()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`ValidConfig::preset`] skips the check on the strength of this test.
    #[test]
    fn every_preset_is_valid_as_it_is() {
        for p in Preset::ALL {
            assert_eq!(Config::preset(p).validated(), Ok(ValidConfig::preset(p)));
        }
    }

    /// Deserialising validates: a knob out of range does not become a valid config.
    #[test]
    fn a_valid_config_read_from_toml_is_validated() {
        let text = toml::to_string(&ValidConfig::default()).unwrap();
        assert_eq!(
            toml::from_str::<ValidConfig>(&text).unwrap(),
            ValidConfig::default()
        );
        let bad = text.replace("sigma_k = ", "sigma_k = 1e308 # ");
        let err = toml::from_str::<ValidConfig>(&bad).unwrap_err();
        assert!(err.to_string().contains("detect.sigma_k = 1e308"), "{err}");
    }
}
