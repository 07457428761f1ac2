"""What every task runs on: the shielded stepping (`shielded_stepping`,
the task's side `stepped_task`, `shield_setpoints`, `step_tally`,
`physics_loop`, `substeps`), the scene every task builds first, actions,
observations, the contact monitor and contact energies, metrics and cost,
snapshots, episode progress, the human's grips and a held tool, the
task's options and defaults, and its motions. The task definitions
(`HrcTask` in tasks/base.py and one module per task) sit beside this
package (docs/architecture.md, "Packages")."""
