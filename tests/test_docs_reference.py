"""The docs are reference: what is, with the command behind each table.

* docs/benchmarks.md stays at most MAX_BENCHMARK_LINES lines, and each of
  its sections with a table names the command that measured it.
* No heading of the docs or the README carries a date (a work log's
  header); history lives in git and CHANGELOG.md.
* Neither the package, the agents, the scripts nor the docs cite this
  project's issues by number (external projects' issues name their
  repository, e.g. 'google-deepmind/labmaze issue 11').
"""

import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
MAX_BENCHMARK_LINES = 400
_TABLE_RULE = re.compile(r'^\|[-| :]+\|$', re.M)
_COMMAND = re.compile(r'`[^`]*(python |scripts/|pytest)[^`]*`', re.S)
_DATED_HEADING = re.compile(r'^#+ .*\b20\d\d-\d\d-\d\d', re.M)
_ISSUE_NUMBER = re.compile(r'\b(issue|pr|pull request)s? ?#?\d+|\(#\d+\)',
                           re.I)
_EXTERNAL_REPOSITORY = re.compile(r'[\w.-]+/[\w.-]+ (issue|pull request)',
                                  re.I)


def _sections(text):
  return re.split(r'\n(?=## )', text)


def issue_citations(text):
  """Lines of `text` that cite an issue by number without naming the
  external repository it belongs to."""
  return [line for line in text.splitlines()
          if _ISSUE_NUMBER.search(line)
          and not _EXTERNAL_REPOSITORY.search(line)]


def sections_without_command(text):
  """Titles of the `## ` sections of `text` with a table but no command."""
  return [section.splitlines()[0] for section in _sections(text)
          if _TABLE_RULE.search(section) and not _COMMAND.search(section)]


def test_benchmarks_is_short_and_every_table_has_its_command():
  text = (ROOT / 'docs' / 'benchmarks.md').read_text()
  assert len(text.splitlines()) <= MAX_BENCHMARK_LINES
  assert sections_without_command(text) == []


def test_checks_can_fail():
  assert sections_without_command(
      '## Speed\n\n| a | b |\n|---|---|\n| 1 | 2 |\n') == ['## Speed']
  assert sections_without_command(
      '## Speed\n`python -m x`\n| a |\n|---|\n') == []
  assert issue_citations('see issue 12 for why') == ['see issue 12 for why']
  assert issue_citations('fixed in (#31)') == ['fixed in (#31)']
  assert issue_citations('google-deepmind/labmaze issue 11, open') == []
  assert _DATED_HEADING.search('## Shield cycle, 2026-11-21\n')


_DOCS = sorted((ROOT / 'docs').rglob('*.md')) + [ROOT / 'README.md']


@pytest.mark.parametrize('path', _DOCS, ids=lambda p: p.name)
def test_no_dated_headings(path):
  assert _DATED_HEADING.findall(path.read_text()) == []


_SOURCES = sorted(p for folder in ('hrc_suite', 'agents', 'scripts')
                  for p in (ROOT / folder).rglob('*.py')) + _DOCS


def test_no_issue_numbers():
  found = [f'{path.relative_to(ROOT)}: {line.strip()}'
           for path in _SOURCES
           for line in issue_citations(path.read_text())]
  assert found == []
