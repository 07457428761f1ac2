"""Imitation variants of SAC as environment wrappers: RSI, SIR, AIR."""

from agents.imitation.rewards import ImitationReward
from agents.imitation.rewards import similarity
from agents.imitation.wrappers import ActionImitationReward
from agents.imitation.wrappers import AGENTS
from agents.imitation.wrappers import NEEDS_DATASET
from agents.imitation.wrappers import ReferenceStateInitialization
from agents.imitation.wrappers import StateImitationReward
from agents.imitation.wrappers import wrap
