"""Tests of agents/config.py."""

import dataclasses
import json

import pytest

from agents import config


def test_reference_preset_has_the_papers_values():
  reference = config.reference_config()
  assert reference.learning_rate == 5e-4
  assert reference.replay_capacity == 1_000_000
  assert reference.min_replay_size == 1000
  assert reference.batch_size == 128
  assert reference.tau == 0.005
  assert reference.discount == 0.99
  # 100 gradient steps every 100 environment steps, in one call.
  assert reference.fused_steps == 100 and reference.updates_per_step == 1.0
  assert reference.initial_temperature == 0.2
  assert reference.hidden_sizes == (64, 64, 64)


def test_default_preset():
  default = config.default_config()
  assert default.learning_rate == 3e-4
  assert default.batch_size == 256
  assert default.hidden_sizes == (256, 256)
  assert default.initial_temperature == 1.0
  assert default.updates_per_step == 1.0
  assert default.fused_steps == config.FUSED_STEPS
  assert default.max_grad_norm is None
  assert default.reward_scale == 1.0


def test_quick_preset():
  quick = config.quick_config()
  assert quick.hidden_sizes == (64, 64) and quick.reward_scale == 100.0
  assert quick.initial_temperature == 0.01 and quick.discount == 0.95
  # Everything else is the default's.
  assert dataclasses.replace(
      quick, hidden_sizes=(256, 256), reward_scale=1.0,
      initial_temperature=1.0, discount=0.99) == config.default_config()


def test_config_from_name_applies_overrides():
  cfg = config.config_from_name('reference', batch_size=64,
                                hidden_sizes=[32, 32])
  assert cfg.batch_size == 64
  assert cfg.hidden_sizes == (32, 32)
  assert cfg.learning_rate == 5e-4
  assert config.config_from_name('default') == config.default_config()


def test_unknown_names_are_rejected():
  with pytest.raises(ValueError, match='Unknown SAC config .*default'):
    config.config_from_name('fast')
  with pytest.raises(ValueError, match='batchsize'):
    config.config_from_name('default', batchsize=3)


@pytest.mark.parametrize('field, value', [
    ('learning_rate', 0.0), ('batch_size', 0), ('batch_size', 2.5),
    ('discount', 1.5), ('tau', 0.0), ('hidden_sizes', ()),
    ('hidden_sizes', (64, 0)), ('initial_temperature', -1.0),
    ('updates_per_step', -1.0), ('fused_steps', 0),
    ('fused_steps', 1.5),
    ('max_grad_norm', 0.0), ('min_replay_size', -1),
    ('target_entropy', float('nan')), ('reward_scale', 0.0)])
def test_bad_values_name_the_field(field, value):
  with pytest.raises(ValueError, match=field):
    config.default_config(**{field: value})


def test_target_entropy_defaults_to_minus_action_size():
  assert config.default_config().entropy_target(4) == -4.0
  assert config.default_config(target_entropy=-1.5).entropy_target(4) == -1.5


def test_json_round_trip_and_frozen():
  cfg = config.reference_config(max_grad_norm=10.0)
  rebuilt = config.SACConfig(**json.loads(json.dumps(cfg.to_dict())))
  assert rebuilt == cfg
  with pytest.raises(dataclasses.FrozenInstanceError):
    cfg.batch_size = 3


def test_from_dict_reads_configs_written_before_fused_steps():
  cfg = config.reference_config()
  assert config.SACConfig.from_dict(cfg.to_dict()) == cfg
  old = cfg.to_dict()
  del old['fused_steps']
  old['update_every'] = 100   # The reference's bursts of 100 steps.
  assert config.SACConfig.from_dict(old) == cfg
  old.update(update_every=10, updates_per_step=0.25)
  with pytest.raises(ValueError, match='2.5 gradient steps per burst'):
    config.SACConfig.from_dict(old)
  with pytest.raises(ValueError, match='both update_every and fused_steps'):
    config.SACConfig.from_dict(dict(cfg.to_dict(), update_every=1))
