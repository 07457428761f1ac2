"""The fixed set of human keypoints every motion clip provides.

A clip stores positions of these keypoints, in this order, over time
(`hrc_suite.human.clip`). The human entity, the shield's human model and the
observations all index keypoints by these names. Z is up, metres.
"""

CENTRE = ('pelvis', 'torso', 'chest', 'neck', 'head')
SIDE = ('shoulder', 'elbow', 'wrist', 'hand', 'hip', 'knee', 'ankle')

KEYPOINT_NAMES = CENTRE + tuple(
    f'{side}_{part}' for side in ('left', 'right') for part in SIDE)
KEYPOINT_INDEX = {name: i for i, name in enumerate(KEYPOINT_NAMES)}
NUM_KEYPOINTS = len(KEYPOINT_NAMES)

# Body segments as (name, proximal keypoint, distal keypoint). The human
# entity's capsules and the shield's body capsules both use these.
SEGMENTS = (
    ('head', 'neck', 'head'),
    ('torso', 'pelvis', 'neck'),
    ('left_upper_arm', 'left_shoulder', 'left_elbow'),
    ('left_forearm', 'left_elbow', 'left_wrist'),
    ('left_hand', 'left_wrist', 'left_hand'),
    ('right_upper_arm', 'right_shoulder', 'right_elbow'),
    ('right_forearm', 'right_elbow', 'right_wrist'),
    ('right_hand', 'right_wrist', 'right_hand'),
    ('left_thigh', 'left_hip', 'left_knee'),
    ('left_shin', 'left_knee', 'left_ankle'),
    ('right_thigh', 'right_hip', 'right_knee'),
    ('right_shin', 'right_knee', 'right_ankle'),
)


def index(names):
  """Indices of keypoint names; unknown names list the valid ones."""
  out = []
  for name in names:
    if name not in KEYPOINT_INDEX:
      raise ValueError(f'Unknown keypoint {name!r}: expected one of '
                       f'{", ".join(KEYPOINT_NAMES)}')
    out.append(KEYPOINT_INDEX[name])
  return out
