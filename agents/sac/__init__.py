"""Soft actor-critic (Haarnoja et al. 2018) in pure JAX, shaped like Acme's."""

from agents.config import SACConfig
from agents.sac.agent import SACAgent

__all__ = ['SACAgent', 'SACConfig']
