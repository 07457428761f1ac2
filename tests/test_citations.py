"""Comments and docstrings cite documents inside the repository.

The shield's maths and the facts about the reference benchmark live in
docs/shield_maths.md and docs/reference_benchmark.md; code must cite those
(e.g. "(docs/shield_maths.md, 4)", "(docs/reference_benchmark.md, Tasks)"),
not the notes they were written from, which are not in the repository.
A section of any document in docs/ is cited by its heading, quoted or as
its first words (e.g. '(docs/benchmarks.md, "SAC training throughput")'),
and that heading must exist.
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
# "docs/<name>.md, <section>" for any document: the section is a quoted
# heading or a heading's first words, as BENCHMARK_SECTION takes them.
SECTION = re.compile(r'(?<![\w./])docs/([\w./-]+\.md),((?:.|\n){0,120})')
# A heading's number: "4. Monitored path and failsafe", "5.2 Reachable ...".
HEADING_NUMBER = re.compile(r'(\d+(?:\.\d+)*)\.?\s+(.*)')


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
  assert 'hrc_suite/safety/shield/shield.py' in names
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


def _section_names(name):
  """What a citation may call the sections of docs/<name>.

  Args:
    name: the document's path inside docs/, e.g. 'benchmarks.md'.

  Returns:
    (names, numbers): every heading (fenced code left out) as written,
    without its number ("4. Timing": "Timing") and without a closing
    parenthesis ("Assumptions (the ...)": "Assumptions"); and the
    headings' numbers ("4", "5.2").
  """
  names, numbers, fenced = set(), set(), False
  for line in (ROOT / 'docs' / name).read_text().splitlines():
    if line.startswith('```'):
      fenced = not fenced
    if fenced or not line.startswith('#'):
      continue
    heading = line.lstrip('#').strip()
    forms = [heading]
    numbered = HEADING_NUMBER.fullmatch(heading)
    if numbered:
      numbers.add(numbered.group(1))
      forms.append(numbered.group(2))
    for form in forms:
      names.add(form)
      names.add(re.sub(r'\s*\(.*\)$', '', form))
  return names, numbers


def _joined(cited):
  """The cited text with its comment lines joined: "A\n  # b" is "A b"."""
  return re.sub(r'\s*\n\s*#?\s*', ' ', cited).strip()


def _cites_a_section(cited, names, numbers):
  """Whether the text after "docs/<name>.md," names one of its sections.

  Args:
    cited: the text, possibly wrapped over comment lines.
    names: the section names of the document (`_section_names`).
    numbers: its section numbers.

  Returns:
    True if the text is a quoted name, starts with a section number
    ("4 and 9", "sections 1, 2 and 10") or starts with a name followed by
    anything but a letter or digit.
  """
  cited = _joined(cited)
  if cited.startswith('"'):
    end = cited.find('"', 1)
    return end > 0 and cited[1:end] in names
  number = re.match(r'(?:sections?\s+)?(\d+(?:\.\d+)*)', cited)
  if number:
    return number.group(1) in numbers
  return any(cited.startswith(name) and not cited[len(name):][:1].isalnum()
             for name in names)


def _bad_section_citations(files):
  """'file:line: citation' for every cited section that does not exist.

  Args:
    files: (name, text) pairs, e.g. `_python_files()`.

  Returns:
    The citations of a document in docs/ whose section is not one of its
    headings (documents that do not exist are `test_cited_docs_exist`'s).
  """
  bad, sections = [], {}
  for name, text in files:
    for match in SECTION.finditer(text):
      doc = match.group(1)
      if not (ROOT / 'docs' / doc).is_file():
        continue
      if doc not in sections:
        sections[doc] = _section_names(doc)
      if not _cites_a_section(match.group(2), *sections[doc]):
        cited = _joined(match.group(2))
        end = cited.find('"', 1) if cited.startswith('"') else -1
        cited = cited[:end + 1] if end > 0 else cited[:40]
        bad.append(f'{name}:{_line(text, match.start())}: docs/{doc}, '
                   f'{cited}')
  return bad


@pytest.mark.parametrize('doc, cited, ok', [
    ('benchmarks.md', ' "SAC training throughput").', True),
    ('benchmarks.md', ' "Where the time of an RL step\n  # goes").', True),
    ('benchmarks.md', ' "Where the time goes").', False),
    ('benchmarks.md', ' "Physics step").', True),
    ('benchmarks.md', ' Shield cycle).', True),
    ('benchmarks.md', ' Shield cycles of one RL step.', True),
    ('benchmarks.md', ' Shield cyc).', False),
    ('shield_maths.md', ' 5.2).', True),
    ('shield_maths.md', ' sections 1, 2 and 10 (B1).', True),
    ('shield_maths.md', ' 5.9).', False),
    ('extending.md', ' "A shield mode"):', True),
    ('safety.md', '\n    Assumptions: Tracking).', True),
    ('tasks.md', ' hammering/default).', True),
    ('tasks.md', ' hammering).', False),
])
def test_section_check(doc, cited, ok):
  assert _cites_a_section(cited, *_section_names(doc)) == ok


def test_a_made_up_section_is_flagged():
  # Built from parts, so that this file does not cite it itself.
  made_up = ('x = 1\n# Speed: see (docs/benchmarks' + '.md, "No such\n'
             '# heading").\n')
  bad = _bad_section_citations([('fake.py', made_up)])
  assert len(bad) == 1 and bad[0].startswith('fake.py:2: '), bad
  assert bad[0].endswith('.md, "No such heading"'), bad
  fine = made_up.replace('No such\n# heading', 'Shield cycle')
  assert not _bad_section_citations([('fake.py', fine)])


def test_cited_sections_of_every_doc_exist():
  bad = _bad_section_citations(_python_files())
  assert not bad, 'no such section:\n' + '\n'.join(bad)
