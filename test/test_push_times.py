"""The push-times file of ``import-bags`` (data/robot_import.py): its format, its errors in
words, and how its rows find their recordings."""
import pytest

from fall_predictor.data.dataset import DatasetError
from fall_predictor.data.robot_import import match_push_times, read_push_times


def _table(tmp_path, text):
    path = tmp_path / 'push_times.csv'
    path.write_text(text)
    return path


def test_seconds_or_nanoseconds_per_row(tmp_path):
    table = read_push_times(_table(tmp_path, 'bag,t_push_s,t_push_ns\n'
                                              'runs/run_1/,1718000012.25,\n'
                                              'run_2,,1718000099500000000\n'))
    assert table == {'runs/run_1': 1718000012.25, 'run_2': 1718000099.5}


@pytest.mark.parametrize('text, words', [
    ('recording,t_push_s\nx,1\n', 'needs the columns bag and t_push_s'),
    ('bag,t_push_s,t_push_ns\nx,1,1000\n', 'once, as t_push_s or t_push_ns'),
    ('bag,t_push_s\nx,\n', 'once, as t_push_s or t_push_ns'),
    ('bag,t_push_s\nx,soon\n', "'soon' is not a number"),
    ('bag,t_push_ns\nx,1.5\n', 'not a whole number of nanoseconds'),
    ('bag,t_push_s\nx,nan\n', 'must be finite'),
    ('bag,t_push_s\nx,1\nx/,2\n', 'line 3: x/ is named twice'),
    ('bag,t_push_s\n,1\n', 'line 2: no bag'),
])
def test_a_file_that_cannot_be_read_says_where_and_why(tmp_path, text, words):
    with pytest.raises(DatasetError, match=words):
        read_push_times(_table(tmp_path, text))


def test_rows_find_recordings_by_path_or_by_name():
    table = {'data/a/run_1': 10.0, 'run_2': 20.0, 'run_9': 90.0}
    times, unused = match_push_times(['data/a/run_1/', 'other/run_2', 'data/run_3'], table)
    assert times == [10.0, 20.0, None] and unused == ['run_9']
    with pytest.raises(DatasetError, match='names it twice'):
        match_push_times(['data/a/run_1'], {'data/a/run_1': 1.0, 'run_1': 1.0})
    with pytest.raises(DatasetError, match='names 2 recordings: give their paths'):
        match_push_times(['a/run_2', 'b/run_2'], table)
