"""Comments and docstrings cite documents inside the repository.

The shield's maths and the facts about the reference benchmark live in
docs/shield_maths.md and docs/reference_benchmark.md; code must cite those
(e.g. "(docs/shield_maths.md, 4)", "(docs/reference_benchmark.md, Tasks)"),
not the notes they were written from, which are not in the repository.
"""

import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGES = ('hrc_suite', 'agents', 'scripts', 'tests')
# Citations of documents outside the repository. Written so that this file
# does not match them itself.
OUTSIDE = re.compile(
    r'shield[- ]spec|reference[-]benchmark|\bspec(?: section)? \d',
    re.IGNORECASE)
# "docs/<name>.md" not preceded by a path (so "../shared/docs/x.md" is not
# taken for the file of that name in the repository's docs).
DOC = re.compile(r'(?<![\w./])docs/([\w./-]+\.md)')
MATHS_SECTION = re.compile(
    r'(?<![\w./])docs/shield_maths\.md,\s*(?:sections?\s+)?(\d+(?:\.\d+)?)')
BENCHMARK_SECTION = re.compile(
    r'(?<![\w./])docs/reference_benchmark\.md,\s*((?:.|\n){0,40})')


def _python_files():
  for package in PACKAGES:
    for path in sorted((ROOT / package).rglob('*.py')):
      yield path.relative_to(ROOT).as_posix(), path.read_text()


def _headings(name):
  text = (ROOT / 'docs' / name).read_text()
  return [line.lstrip('#').strip() for line in text.splitlines()
          if line.startswith('#')]


def _line(text, index):
  return text.count('\n', 0, index) + 1


def test_python_files_are_found():
  names = [name for name, _ in _python_files()]
  assert 'hrc_suite/safety/shield.py' in names
  assert 'tests/test_citations.py' in names


def test_the_outside_pattern_catches_the_old_citations():
  for old in ('(shield-sp' + 'ec 3.2)', 'reference' + '-benchmark.md',
              '(spec ' + '2.4)', 'shield sp' + 'ec section 9',
              '(spec section ' + '2.3)'):
    assert OUTSIDE.search(old), old
  for fine in ('action_spec', 'spec, buffers', 'the spec of timestep'):
    assert not OUTSIDE.search(fine), fine


def test_no_citation_of_documents_outside_the_repository():
  found = []
  for name, text in _python_files():
    for match in OUTSIDE.finditer(text):
      found.append(f'{name}:{_line(text, match.start())}: {match.group(0)}')
  assert not found, 'cite docs/ instead:\n' + '\n'.join(found)


def test_cited_docs_exist():
  missing = []
  for name, text in _python_files():
    for match in DOC.finditer(text):
      if not (ROOT / 'docs' / match.group(1)).is_file():
        missing.append(f'{name}:{_line(text, match.start())}: '
                       f'docs/{match.group(1)}')
  assert not missing, 'cited but not in the repository:\n' + '\n'.join(
      missing)


def test_cited_shield_maths_sections_exist():
  numbers = {heading.split()[0].rstrip('.')
             for heading in _headings('shield_maths.md')
             if heading[:1].isdigit()}
  assert {'1', '4', '5.2', '8.3', '10'} <= numbers
  bad = []
  for name, text in _python_files():
    for match in MATHS_SECTION.finditer(text):
      if match.group(1) not in numbers:
        bad.append(f'{name}:{_line(text, match.start())}: {match.group(0)}')
  assert not bad, 'no such section in docs/shield_maths.md:\n' + '\n'.join(
      bad)


@pytest.mark.parametrize('cited, ok', [('Tasks).', True),
                                       ('Training\n# and evaluation)', True),
                                       ('Decision).', False)])
def test_benchmark_section_check(cited, ok):
  assert _names_a_section(cited, _headings('reference_benchmark.md')) == ok


def _names_a_section(cited, headings):
  # Join a name wrapped over comment lines: "Training\n# and evaluation".
  cited = re.sub(r'\s*\n\s*#?\s*', ' ', cited)
  return any(cited.startswith(heading) for heading in headings)


def test_cited_reference_benchmark_sections_exist():
  headings = _headings('reference_benchmark.md')
  bad = []
  for name, text in _python_files():
    for match in BENCHMARK_SECTION.finditer(text):
      if not _names_a_section(match.group(1), headings):
        bad.append(f'{name}:{_line(text, match.start())}: {match.group(0)!r}')
  assert not bad, ('no such section in docs/reference_benchmark.md:\n'
                   + '\n'.join(bad))
