// octovk store: placeholder
