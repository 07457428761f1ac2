"""The CSV logger: columns, widening on resume, truncation."""

import os

from agents import logging as logging_lib


def test_resumed_file_widens_for_new_columns(tmp_path):
  path = os.path.join(tmp_path, 'train.csv')
  first = logging_lib.CSVLogger(path)
  first.write({'return': 1.5}, step=10)
  first.write({'return': 2.5}, step=20)
  first.close()

  resumed = logging_lib.CSVLogger(path)
  resumed.write({'return': 3.5, 'contact_energy': 0.25}, step=30)
  resumed.write({'return': 4.5}, step=40)
  resumed.close()

  rows = logging_lib.read_csv(path)
  assert logging_lib.CSVLogger(path).columns == [
      'step', 'return', 'contact_energy']
  assert [row['step'] for row in rows] == ['10', '20', '30', '40']
  assert [row['return'] for row in rows] == ['1.5', '2.5', '3.5', '4.5']
  assert [row['contact_energy'] for row in rows] == ['', '', '0.25', '']


def test_truncate_keeps_rows_up_to_the_step(tmp_path):
  path = os.path.join(tmp_path, 'eval.csv')
  logger = logging_lib.CSVLogger(path)
  for step in (0, 100, 200, 300):
    logger.write({'success': step / 300}, step=step)
  logger.truncate(200)
  logger.write({'success': 0.5}, step=300)
  logger.close()
  rows = logging_lib.read_csv(path)
  assert [row['step'] for row in rows] == ['0', '100', '200', '300']
  assert rows[-1]['success'] == '0.5'
